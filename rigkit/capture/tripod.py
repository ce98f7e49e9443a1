"""Where the tripod stood and where the laser pointed: the session's georeferencing
inputs, as ``session.yaml`` keeps them (``tripod:``, and each reading's
``azimuth_deg``), with the checks on their values.

Conventions: latitude and longitude in degrees on WGS 84 (north and east positive);
height in metres as the source gives it (a GPS's GGA sentence: above mean sea level);
azimuth in degrees clockwise from north as the laser reports it (true or magnetic north:
the rig profile's ``rangefinder.azimuth`` says which), in [0, 360); inclination in
degrees above the horizontal, in [-90, 90].
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

from rigkit.core.yamlfile import KeyPath
from rigkit.errors import InputError

TRIPOD_KEY = "tripod"
"""The top-level key of ``session.yaml`` holding :class:`TripodPosition`."""
HEIGHT_RANGE_M = (-1000.0, 10000.0)
"""Plausible heights: below this a sign or unit is wrong."""


@dataclass(frozen=True)
class TripodPosition:
    """Where the tripod stood at the left position (the left camera's optical centre, to
    the precision of the source). ``source``: ``manual`` (typed in) or ``gps:<port>``
    (``fixes`` GGA fixes averaged; ``raw`` the last sentence, for audit)."""

    lat_deg: float
    lon_deg: float
    height_m: float
    source: str
    time_utc: str
    fixes: int | None = None
    raw: str | None = None


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
                                        "time_utc"), optional=("fixes", "raw"))
    lat, lon, height = (key.child(name).number(keys[name], unit) for name, unit in
                        (("lat_deg", "degrees"), ("lon_deg", "degrees"), ("height_m", "m")))
    try:
        check_position(lat, lon, height)
    except InputError as exc:
        raise key.error(str(exc)) from None
    return TripodPosition(
        lat_deg=lat, lon_deg=lon, height_m=height,
        source=key.child("source").line(keys["source"]),
        time_utc=key.child("time_utc").line(keys["time_utc"]),
        fixes=key.optional(keys, "fixes", lambda v, k: k.integer(v, "fixes", 1_000_000)),
        raw=key.optional(keys, "raw", lambda v, k: k.text(v, strip=False)),
    )


def tripod_to_data(tripod: TripodPosition) -> dict[str, Any]:
    data: dict[str, Any] = {
        "lat_deg": tripod.lat_deg, "lon_deg": tripod.lon_deg, "height_m": tripod.height_m,
        "source": tripod.source, "time_utc": tripod.time_utc,
    }
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
