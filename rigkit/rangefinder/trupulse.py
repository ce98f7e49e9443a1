"""Laser Technology TruPulse 200/360 (LTI "Criterion 400" / CR400 format, NMEA-0183
style): the device *pushes* ``$PLTIT,...*CS<CR><LF>`` sentences after each shot the user
fires; XOR checksum; units feet, yards or metres (see ``docs/rangefinder.md``)."""

from __future__ import annotations

import math

from rigkit.errors import InputError
from rigkit.rangefinder.framing import (
    FrameError,
    Notice,
    Reading,
    ascii_text,
    parse_decimal,
    short,
    split_checksum,
    split_frames,
)

TRUPULSE_MAX_RANGE_M = 2000.0
"""The longest range a TruPulse 200/360 measures (to a reflective target), m."""
FOOT_M = 0.3048
"""One international foot in metres (exact)."""
YARD_M = 0.9144
"""One international yard in metres (exact)."""

# TruPulse unit letter -> (unit name reported in Reading.unit, metres per unit).
TRUPULSE_UNITS: dict[str, tuple[str, float]] = {
    "M": ("m", 1.0),
    "F": ("ft", FOOT_M),
    "Y": ("yd", YARD_M),
}




def nmea_checksum(body: bytes) -> int:
    """XOR of all bytes of ``body`` (the characters between ``$`` and ``*``)."""
    value = 0
    for byte in body:
        value ^= byte
    return value


def trupulse_sentence(fields: list[str]) -> bytes:
    """``$`` + comma-joined fields + ``*`` + two-digit hex XOR checksum + CR LF."""
    body = ",".join(fields).encode("ascii")
    return b"$" + body + b"*" + f"{nmea_checksum(body):02X}".encode("ascii") + b"\r\n"


def _trupulse_distance(value: str, unit: str, what: str) -> tuple[float, bool | None]:
    """Metres and the low-quality flag from a TruPulse distance field.

    The TruPulse sends distances with two decimals, of which the last is not a
    digit of the distance but a flag: 0 = high-quality target, 1 = low-quality
    target (resolution is 0.1 unit). A value that does not follow that pattern
    is taken at face value with no quality flag.
    """
    if unit not in TRUPULSE_UNITS:
        raise FrameError(f"unknown {what} unit {unit!r} (expected F, Y or M)")
    per_unit = TRUPULSE_UNITS[unit][1]
    _, dot, decimals = value.partition(".")
    quality: bool | None = None
    number = value
    if dot and len(decimals) == 2 and decimals[1] in "01":
        number, quality = value[:-1], decimals[1] == "1"
    amount = parse_decimal(number, what)
    if amount < 0:
        raise FrameError(f"{what} {value!r} is not a distance")
    metres = round(amount * per_unit, 6)
    if metres > TRUPULSE_MAX_RANGE_M:
        raise FrameError(f"{what} {metres:g} m is beyond the TruPulse's "
                         f"{TRUPULSE_MAX_RANGE_M:g} m")
    return metres, quality


def _angle(value: str, unit: str, what: str) -> float | None:
    if value == "":
        return None
    if unit != "D":
        raise FrameError(f"unknown {what} unit {unit!r} (expected D)")
    angle = parse_decimal(value, what)
    low, high = _ANGLES[what]
    if not low <= angle <= high:
        raise FrameError(f"{what} {angle:g} deg is outside {low:g}-{high:g} deg")
    return angle


_ANGLES = {"inclination": (-90.0, 90.0), "azimuth": (0.0, 360.0)}
"""The range of each angle a TruPulse reports, degrees."""

# Number of data fields after the message type, per TruPulse sentence type.
_TRUPULSE_FIELDS = {"HV": 8, "ML": 8, "HT": 2}


def parse_trupulse(frame: bytes, timestamp: float) -> Reading | Notice:
    """Parse one TruPulse sentence (without or with its CR LF).

    ``$PLTIT,HV,<HD>,<u>,<AZ>,D,<INC>,D,<SD>,<u>*CS`` with a slope distance is
    a :class:`Reading` (``timestamp``: receive time, seconds since the epoch).
    Everything else that is well formed is a :class:`Notice`: an HV without
    distance (inclination-only shot), HT (height), ML (missing line), ID, and
    unknown types or talkers (``known=False``). A trailing comma before ``*``
    (as in some manual examples) is accepted. Raises :class:`ChecksumError`
    on a checksum mismatch and :class:`FrameError` on anything malformed.
    """
    text = ascii_text(frame)
    fields = split_checksum(text, "$", nmea_checksum).split(",")
    if fields[0] != "PLTIT":
        return Notice(kind=fields[0], fields=tuple(fields[1:]), raw=frame, known=False)
    if len(fields) < 2 or not fields[1]:
        raise FrameError(f"$PLTIT sentence without a message type: {short(text)!r}")
    kind, values = fields[1], fields[2:]
    if kind not in _TRUPULSE_FIELDS:
        known = kind == "ID"
        if known and values and values[-1] == "":
            values = values[:-1]
        return Notice(kind=kind, fields=tuple(values), raw=frame, known=known)
    wanted = _TRUPULSE_FIELDS[kind]
    if len(values) == wanted + 1 and values[-1] == "":
        values = values[:-1]
    if len(values) != wanted:
        raise FrameError(f"{kind} sentence has {len(values)} fields, expected {wanted}")
    if kind != "HV":
        return Notice(kind=kind, fields=tuple(values), raw=frame)
    hd, hd_unit, az, az_unit, inc, inc_unit, sd, sd_unit = values
    inclination = _angle(inc, inc_unit, "inclination")
    azimuth = _angle(az, az_unit, "azimuth")
    if azimuth is not None:
        azimuth %= 360.0  # a bearing of 360.00 is north, as 0.00 is
    if sd == "":
        return Notice(kind="HV", fields=tuple(values), raw=frame)
    slope, quality = _trupulse_distance(sd, sd_unit, "slope distance")
    horizontal = None if hd == "" else _trupulse_distance(hd, hd_unit, "horizontal distance")[0]
    return Reading(
        slope_distance_m=slope,
        horizontal_distance_m=horizontal,
        inclination_deg=inclination,
        azimuth_deg=azimuth,
        unit=TRUPULSE_UNITS[sd_unit][0],
        timestamp=timestamp,
        raw=frame,
        protocol="trupulse",
        targets_m=(slope,),
        low_quality=quality,
    )


def _trupulse_value(metres: float, per_unit: float, low_quality: bool) -> str:
    return f"{metres / per_unit:.1f}" + ("1" if low_quality else "0")


def encode_trupulse_hv(
    slope_distance_m: float,
    *,
    inclination_deg: float,
    azimuth_deg: float | None,
    unit: str = "M",
    low_quality: bool = False,
) -> bytes:
    """The HV sentence a TruPulse sends for a shot (distances in metres).

    Distances are sent in ``unit`` (``"M"``, ``"F"`` or ``"Y"``) at 0.1-unit
    resolution followed by the quality digit; the horizontal distance is
    slope x cos(inclination). ``azimuth_deg=None`` leaves the field empty.
    """
    if unit not in TRUPULSE_UNITS:
        raise InputError(f"unknown TruPulse unit {unit!r} (choose M, F or Y)")
    per_unit = TRUPULSE_UNITS[unit][1]
    horizontal = slope_distance_m * math.cos(math.radians(inclination_deg))
    return trupulse_sentence(
        [
            "PLTIT",
            "HV",
            _trupulse_value(horizontal, per_unit, low_quality),
            unit,
            "" if azimuth_deg is None else f"{azimuth_deg:.2f}",
            "" if azimuth_deg is None else "D",
            f"{inclination_deg:.2f}",
            "D",
            _trupulse_value(slope_distance_m, per_unit, low_quality),
            unit,
        ]
    )


def split_trupulse(buffer: bytes) -> tuple[list[bytes], bytes]:
    """:func:`split_frames` for TruPulse: ``$`` ... CR and/or LF."""
    return split_frames(buffer, start=b"$", terminators=b"\r\n")
