"""Where the tripod stood and where the laser pointed: the session's georeferencing
inputs, as ``session.yaml`` keeps them (``tripod:``, and each reading's
``azimuth_deg``), with the checks on their values.

Conventions: latitude and longitude in degrees on WGS 84 (north and east positive);
height in metres as the source gives it, with what it is measured from (its datum,
:data:`HEIGHT_DATUMS`: a GPS's GGA sentence gives the height above the receiver's own
mean sea level and the geoid's separation from the ellipsoid, kept with it);
azimuth in degrees clockwise from north as the laser reports it (true or magnetic north:
the rig profile's ``rangefinder.azimuth`` says which), in [0, 360); inclination in
degrees above the horizontal, in [-90, 90].
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from rigkit.core.yamlfile import KeyPath
from rigkit.errors import InputError

TRIPOD_KEY = "tripod"
"""The top-level key of ``session.yaml`` holding :class:`TripodPosition`."""
HEIGHT_RANGE_M = (-1000.0, 10000.0)
"""Plausible heights: below this a sign or unit is wrong."""
GEOID_RANGE_M = (-150.0, 150.0)
"""The geoid lies within about 110 m of the WGS 84 ellipsoid everywhere."""

HEIGHT_GPS = "gps"
HEIGHT_ELLIPSOIDAL = "ellipsoidal"
HEIGHT_UNKNOWN = "unknown"
HEIGHT_DATUMS = {
    HEIGHT_GPS: "above mean sea level as the GPS receiver's geoid model gives it (GGA's "
    "altitude; GGA does not name the model)",
    HEIGHT_ELLIPSOIDAL: "above the WGS 84 ellipsoid",
    "EPSG:<code>": "in that vertical CRS (EPSG:5728: LN02 height, EPSG:3855: EGM2008 "
    "height, ...)",
    HEIGHT_UNKNOWN: "typed in without saying what it is measured from",
}
"""What a tripod's ``height_datum`` may be, and what each says of its height."""


@dataclass(frozen=True)
class TripodPosition:
    """Where the tripod stood at the left position (the left camera's optical centre, to
    the precision of the source). ``source``: ``manual`` (typed in) or ``gps:<port>``
    (``fixes`` GGA fixes averaged; ``raw`` the last sentence, for audit).
    ``height_datum``: what ``height_m`` is measured from (:data:`HEIGHT_DATUMS`);
    ``geoid_separation_m``: the geoid's height above the WGS 84 ellipsoid there, m, as
    the GPS sent it (None: not known)."""

    lat_deg: float
    lon_deg: float
    height_m: float
    source: str
    time_utc: str
    fixes: int | None = None
    raw: str | None = None
    geoid_separation_m: float | None = None
    height_datum: str = HEIGHT_UNKNOWN

    @property
    def ellipsoidal_height_m(self) -> float | None:
        """The height above the WGS 84 ellipsoid where the position itself says it (an
        ellipsoidal height, or a GPS's with its geoid separation), else None."""
        if self.height_datum == HEIGHT_ELLIPSOIDAL:
            return self.height_m
        if self.height_datum == HEIGHT_GPS and self.geoid_separation_m is not None:
            return self.height_m + self.geoid_separation_m
        return None


def check_height_datum(text: str) -> str:
    """``text`` as a tripod's ``height_datum`` (:data:`HEIGHT_DATUMS`; an EPSG code's
    form only: whether PROJ knows it as a vertical CRS is for export to say);
    InputError naming it otherwise."""
    upper = text.strip().upper()
    if upper.startswith("EPSG:") and upper[5:].isdigit() and len(upper) <= 12:
        return upper
    if text.strip().lower() in (HEIGHT_GPS, HEIGHT_ELLIPSOIDAL, HEIGHT_UNKNOWN):
        return text.strip().lower()
    raise InputError(f"height datum {text!r}: expected ellipsoidal, gps, unknown or "
                     "EPSG:<code> of a vertical CRS (e.g. EPSG:5728)")


def check_position(lat_deg: float, lon_deg: float, height_m: float) -> None:
    """InputError naming the value when a position is not on the Earth's surface."""
    for name, value, low, high in (
        ("latitude", lat_deg, -90.0, 90.0),
        ("longitude", lon_deg, -180.0, 180.0),
        ("height", height_m, *HEIGHT_RANGE_M),
    ):
        if not (math.isfinite(value) and low <= value <= high):
            unit = "m" if name == "height" else "degrees"
            raise InputError(f"{name} {value:g}: expected {low:g} to {high:g} {unit}")


def enu_direction(azimuth_deg: float, inclination_deg: float) -> np.ndarray:
    """(east, north, up) unit vector (3,) of a line of sight ``azimuth_deg`` clockwise
    from true north and ``inclination_deg`` above the horizontal."""
    a, i = math.radians(azimuth_deg), math.radians(inclination_deg)
    return np.array([math.cos(i) * math.sin(a), math.cos(i) * math.cos(a), math.sin(i)])


def direction_angles(enu: np.ndarray) -> tuple[float, float]:
    """(azimuth in [0, 360), inclination) in degrees of an (east, north, up) vector (3,)
    of any length: the inverse of :func:`enu_direction`."""
    east, north, up = (float(c) for c in enu)
    return (math.degrees(math.atan2(east, north)) % 360.0,
            math.degrees(math.atan2(up, math.hypot(east, north))))


def check_direction(azimuth_deg: float | None, inclination_deg: float | None) -> None:
    """InputError naming the value for an azimuth outside [0, 360) or an inclination
    outside [-90, 90] degrees (None: not given, accepted)."""
    if azimuth_deg is not None and not (math.isfinite(azimuth_deg)
                                        and 0.0 <= azimuth_deg < 360.0):
        raise InputError(f"azimuth {azimuth_deg:g}: expected 0 to 360 degrees (clockwise "
                         "from north)")
    if inclination_deg is not None and not (math.isfinite(inclination_deg)
                                            and -90.0 <= inclination_deg <= 90.0):
        raise InputError(f"inclination {inclination_deg:g}: expected -90 to 90 degrees "
                         "(above the horizontal)")


def tripod_from_data(value: Any, key: KeyPath) -> TripodPosition:
    """The ``tripod:`` mapping of session.yaml; InputError naming file, key and value."""
    keys = key.mapping(value, required=("lat_deg", "lon_deg", "height_m", "source",
                                        "time_utc"),
                       optional=("fixes", "raw", "geoid_separation_m", "height_datum"))
    lat, lon, height = (key.child(name).number(keys[name], unit) for name, unit in
                        (("lat_deg", "degrees"), ("lon_deg", "degrees"), ("height_m", "m")))
    try:
        check_position(lat, lon, height)
    except InputError as exc:
        raise key.error(str(exc)) from None
    source = key.child("source").line(keys["source"])
    return TripodPosition(
        lat_deg=lat, lon_deg=lon, height_m=height, source=source,
        time_utc=key.child("time_utc").line(keys["time_utc"]),
        fixes=key.optional(keys, "fixes", lambda v, k: k.integer(v, "fixes", 1_000_000)),
        raw=key.optional(keys, "raw", lambda v, k: k.text(v, strip=False)),
        geoid_separation_m=key.optional(keys, "geoid_separation_m", _separation),
        # Written since rigkit keeps it; a GPS's position from before was GGA's altitude.
        height_datum=key.optional(keys, "height_datum", _datum) or (
            HEIGHT_GPS if source.startswith("gps:") else HEIGHT_UNKNOWN),
    )


def _separation(value: Any, key: KeyPath) -> float:
    separation = key.number(value, "m")
    if not GEOID_RANGE_M[0] <= separation <= GEOID_RANGE_M[1]:
        raise key.error(f"must be within {GEOID_RANGE_M[0]:g} to {GEOID_RANGE_M[1]:g} m",
                        value)
    return separation


def _datum(value: Any, key: KeyPath) -> str:
    try:
        return check_height_datum(key.line(value))
    except InputError as exc:
        raise key.error(str(exc)) from None


def tripod_to_data(tripod: TripodPosition) -> dict[str, Any]:
    data: dict[str, Any] = {
        "lat_deg": tripod.lat_deg, "lon_deg": tripod.lon_deg, "height_m": tripod.height_m,
        "source": tripod.source, "time_utc": tripod.time_utc,
    }
    data["height_datum"] = tripod.height_datum
    if tripod.geoid_separation_m is not None:
        data["geoid_separation_m"] = tripod.geoid_separation_m
    if tripod.fixes is not None:
        data["fixes"] = tripod.fixes
    if tripod.raw is not None:
        data["raw"] = tripod.raw
    return data


def azimuth_from_data(value: Any, key: KeyPath) -> float:
    """A reading's ``azimuth_deg``: degrees in [0, 360)."""
    azimuth = key.number(value, "degrees")
    if not 0.0 <= azimuth < 360.0:
        raise key.error("must be at least 0 and under 360 degrees", value)
    return azimuth
