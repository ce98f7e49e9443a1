"""Pure parsing and encoding of laser-rangefinder serial protocols.

Nothing here touches a port or a clock: every function maps bytes to values
(or values to bytes), so the whole module is testable with scripted bytes.

Two protocols with different shapes sit behind one seam (:class:`ProtocolSpec`):

``trupulse``
    Laser Technology TruPulse 200/360 (LTI "Criterion 400" / CR400 format,
    NMEA-0183 style): the device *pushes* ``$PLTIT,...*CS<CR><LF>`` sentences
    after each shot the user fires; XOR checksum; units feet, yards or metres.
``vectronix``
    Safran Vectronix LRF module ``>LM,...*CS<CR>`` command/response protocol
    (LRF 6019/6042/6742/7047 integrator manuals): the host must *request* each
    range; the module acknowledges, answers with up to five targets in
    centimetres and ends with a one-character prompt; additive checksum.

Frame layouts and the published example frames used as test vectors are from
the vendors' user/integrator manuals; see ``docs/rangefinder.md``.

Conventions: distances in metres, angles in degrees, inclination positive
above the horizontal, azimuth clockwise from north as the device reports it.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from datetime import UTC, datetime

from rigkit.errors import InputError, RigkitError

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

MAX_FRAME_BYTES = 128
"""A frame start with no terminator after this many bytes is line noise."""


class RangefinderError(RigkitError):
    """Base class for rangefinder problems; the message is one line."""


class FrameError(RangefinderError):
    """Bytes that are not a well-formed frame of the protocol (noise, a cut line)."""


class ChecksumError(FrameError):
    """A frame whose checksum does not match its contents; never a reading."""


@dataclass(frozen=True)
class Reading:
    """One range measurement.

    ``slope_distance_m`` is the range along the laser's line of sight in metres.
    ``horizontal_distance_m`` is the device's horizontal projection
    (slope x cos(inclination)) in metres, ``None`` when not reported.
    ``inclination_deg`` is degrees above the horizontal (negative: below).
    ``azimuth_deg`` is the device's compass bearing in degrees, ``None`` when
    absent (a TruPulse 200 sends a dummy 0.00, which is passed through).
    ``unit`` is the unit the device sent the distance in: ``"m"``, ``"ft"``,
    ``"yd"`` or ``"cm"``. ``timestamp`` is when the frame was received, in
    seconds since the Unix epoch (UTC). ``raw`` is the frame exactly as
    received, without its line terminator. ``low_quality`` is the TruPulse
    target-quality flag (``None`` when the device does not report one).
    ``targets_m`` lists every valid target range in metres, best first.
    """

    slope_distance_m: float
    horizontal_distance_m: float | None
    inclination_deg: float | None
    azimuth_deg: float | None
    unit: str
    timestamp: float
    raw: bytes
    protocol: str
    targets_m: tuple[float, ...]
    low_quality: bool | None = None

    def to_json_dict(self) -> dict[str, object]:
        """A JSON-serialisable dict; ``raw`` becomes ASCII with escapes."""
        return {
            "slope_distance_m": self.slope_distance_m,
            "horizontal_distance_m": self.horizontal_distance_m,
            "inclination_deg": self.inclination_deg,
            "azimuth_deg": self.azimuth_deg,
            "unit": self.unit,
            "low_quality": self.low_quality,
            "targets_m": list(self.targets_m),
            "protocol": self.protocol,
            "timestamp": self.timestamp,
            "time_utc": datetime.fromtimestamp(self.timestamp, UTC).isoformat(),
            "raw": escape_bytes(self.raw),
        }


@dataclass(frozen=True)
class Notice:
    """A well-formed frame that carries no range.

    Examples: a TruPulse height (HT), missing-line (ML) or ID sentence, an
    inclination-only shot, a Vectronix acknowledgement or prompt. ``known`` is
    False for sentence types the protocol does not define. ``error`` is set
    when the device reports a failure (a rejected command, no valid target).
    """

    kind: str
    fields: tuple[str, ...]
    raw: bytes
    known: bool = True
    error: str | None = None


Parser = Callable[[bytes, float], "Reading | Notice"]
Splitter = Callable[[bytes], "tuple[list[bytes], bytes]"]


@dataclass(frozen=True)
class ProtocolSpec:
    """Everything the driver needs to know about one protocol.

    ``split`` cuts complete frames (and the noise between them) off the front
    of a byte buffer and returns them with the unfinished rest; ``parse`` maps
    one frame to a :class:`Reading` or :class:`Notice` (raising
    :class:`FrameError`/:class:`ChecksumError`). ``request`` is the command
    that fires one measurement and ``request_by_default`` says the device
    measures only on request.
    ``min_request_interval_s`` is the shortest allowed time between requests.
    """

    name: str
    description: str
    default_baud: int
    split: Splitter
    parse: Parser
    request: bytes
    request_by_default: bool
    min_request_interval_s: float


def escape_bytes(data: bytes) -> str:
    """ASCII text for bytes, with ``\\r``, ``\\n`` and ``\\xNN`` escapes (lossless)."""
    return repr(bytes(data))[2:-1]


def _ascii(frame: bytes) -> str:
    try:
        return frame.decode("ascii").strip()
    except UnicodeDecodeError:
        raise FrameError(f"non-ASCII bytes in frame {escape_bytes(frame[:60])}") from None


def _short(text: str) -> str:
    return text if len(text) <= 60 else text[:57] + "..."


def split_frames(
    buffer: bytes, *, start: bytes, terminators: bytes, singles: bytes = b""
) -> tuple[list[bytes], bytes]:
    """Cut complete frames off the front of ``buffer``.

    A frame runs from a ``start`` byte to the first byte in ``terminators``
    (the terminator is dropped). Bytes outside frames come back as their own
    chunks (which then fail to parse and are counted as noise), a frame cut
    short by a new ``start`` byte comes back as such a chunk too, and each byte
    of ``singles`` outside a frame is a one-byte frame (Vectronix prompts).
    Whitespace-only gaps (stray CR/LF) are dropped. Returns the chunks, in
    order, and the unfinished rest to prepend to the next bytes.
    """
    chunks: list[bytes] = []
    i = 0
    n = len(buffer)
    stops = set(terminators) | set(singles) | set(start)
    while i < n:
        if buffer[i] in singles:
            chunks.append(buffer[i : i + 1])
            i += 1
            continue
        j = i
        while j < n and buffer[j] not in start and buffer[j] not in singles:
            j += 1
        if j > i:
            junk = buffer[i:j]
            if junk.strip():
                chunks.append(junk)
            i = j
            continue
        # buffer[i] is a start byte: look for where this frame stops.
        k = i + 1
        while k < n and buffer[k] not in stops:
            k += 1
        if k == n:
            if n - i > MAX_FRAME_BYTES:
                chunks.append(buffer[i:])
                return chunks, b""
            return chunks, buffer[i:]
        chunks.append(buffer[i:k])
        i = k + 1 if buffer[k] in terminators else k
    return chunks, b""


# --------------------------------------------------------------------------
# Laser Technology TruPulse (CR400 / $PLTIT sentences)


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


def _split_checksum(text: str, lead: str, checksum: Callable[[bytes], int]) -> str:
    """Check ``lead``...``*HH`` framing and the checksum; return the body."""
    if not text.startswith(lead):
        raise FrameError(f"not a frame (no leading {lead!r}): {_short(text)!r}")
    star = text.rfind("*")
    if star == -1:
        raise FrameError(f"frame without checksum: {_short(text)!r}")
    body, given = text[1:star], text[star + 1 :]
    if len(given) != 2 or any(c not in "0123456789abcdefABCDEF" for c in given):
        raise FrameError(f"malformed checksum {given!r} in {_short(text)!r}")
    expected = checksum(body.encode("ascii"))
    if int(given, 16) != expected:
        raise ChecksumError(
            f"bad checksum {given.upper()} (computed {expected:02X}) in {_short(text)!r}"
        )
    return body


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
    try:
        amount = float(number)
    except ValueError:
        raise FrameError(f"{what} {value!r} is not a number") from None
    if not math.isfinite(amount) or amount < 0:
        raise FrameError(f"{what} {value!r} is not a distance")
    return round(amount * per_unit, 6), quality


def _angle(value: str, unit: str, what: str) -> float | None:
    if value == "":
        return None
    if unit != "D":
        raise FrameError(f"unknown {what} unit {unit!r} (expected D)")
    try:
        angle = float(value)
    except ValueError:
        raise FrameError(f"{what} {value!r} is not a number") from None
    if not math.isfinite(angle):
        raise FrameError(f"{what} {value!r} is not a number")
    return angle


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
    text = _ascii(frame)
    fields = _split_checksum(text, "$", nmea_checksum).split(",")
    if fields[0] != "PLTIT":
        return Notice(kind=fields[0], fields=tuple(fields[1:]), raw=frame, known=False)
    if len(fields) < 2 or not fields[1]:
        raise FrameError(f"$PLTIT sentence without a message type: {_short(text)!r}")
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


# --------------------------------------------------------------------------
# Safran Vectronix LRF modules (>LM,...*CS<CR>)

VECTRONIX_NACK = {
    "0": "message checksum error",
    "1": "message not supported",
    "2": "invalid parameter",
    "3": "parity error",
    "4": "receive overflow",
    "5": "other error",
}
"""Meaning of the error id in a Vectronix ``>NA,<id>`` not-acknowledge frame."""

VECTRONIX_TARGETS = (3, 5)
"""Target counts a Vectronix range request (``Md``) accepts."""


def additive_checksum(body: bytes) -> int:
    """Sum of all bytes of ``body`` modulo 256 (Vectronix LRF checksum)."""
    return sum(body) & 0xFF


def vectronix_frame(body: str) -> bytes:
    """``>`` + body + ``*`` + two-digit hex additive checksum + CR."""
    data = body.encode("ascii")
    return b">" + data + b"*" + f"{additive_checksum(data):02X}".encode("ascii") + b"\r"


def vectronix_range_field(distance_m: float | None, error_code: str = "000E301") -> str:
    """One 8-character range field: ``v`` + centimetres, or ``R`` + error code."""
    if distance_m is None:
        return "R" + error_code
    return f"v{round(distance_m * 100):07d}"


def parse_vectronix(frame: bytes, timestamp: float) -> Reading | Notice:
    """Parse one Vectronix LRF frame (without or with its CR).

    A range response ``>LM,Md,<r1>,<r2>,...*CS`` with at least one valid range
    (``v`` + 7-digit centimetres) is a :class:`Reading` whose slope distance is
    the first valid target (the module sorts targets by merit) and whose
    ``targets_m`` lists all valid targets. ``R`` (invalid) and ``T`` (module
    outside its temperature range, accuracy not guaranteed) fields are not
    ranges; a response with none valid is a :class:`Notice` with ``error``.
    ``Mf`` (the module's fake-range self test) parses the same way. ``>AC``
    (acknowledge) and the prompts ``<`` (success) and ``!`` (failure, an error
    notice) are notices; ``>NA,<id>`` is a not-acknowledge notice with error.
    """
    text = _ascii(frame)
    if text == "<":
        return Notice(kind="prompt", fields=(), raw=frame)
    if text == "!":
        return Notice(kind="prompt", fields=(), raw=frame, error="the module reported a failure")
    fields = _split_checksum(text, ">", additive_checksum).split(",")
    if fields == ["AC"]:
        return Notice(kind="AC", fields=(), raw=frame)
    if fields[0] == "NA" and len(fields) == 2:
        meaning = VECTRONIX_NACK.get(fields[1], "undocumented error id")
        error = f"the module rejected the command (NACK {fields[1]}: {meaning})"
        return Notice(kind="NA", fields=(fields[1],), raw=frame, error=error)
    if fields[0] != "LM" or len(fields) < 2:
        return Notice(kind=fields[0], fields=tuple(fields[1:]), raw=frame, known=False)
    message, values = fields[1], fields[2:]
    if message not in ("Md", "Mf"):
        return Notice(kind=message, fields=tuple(values), raw=frame)
    if not values:
        raise FrameError(f"range response without ranges: {_short(text)!r}")
    ranges: list[float] = []
    codes: list[str] = []
    for value in values:
        if len(value) != 8 or value[0] not in "vRT":
            raise FrameError(f"malformed range field {value!r} in {_short(text)!r}")
        if value[0] == "v":
            if not value[1:].isdigit():
                raise FrameError(f"range {value!r} is not a number of centimetres")
            ranges.append(int(value[1:]) / 100.0)
        else:
            codes.append(value)
    if not ranges:
        error = f"no valid range (the module reported {', '.join(codes)})"
        return Notice(kind=message, fields=tuple(values), raw=frame, error=error)
    return Reading(
        slope_distance_m=ranges[0],
        horizontal_distance_m=None,
        inclination_deg=None,
        azimuth_deg=None,
        unit="cm",
        timestamp=timestamp,
        raw=frame,
        protocol="vectronix",
        targets_m=tuple(ranges),
    )


def split_vectronix(buffer: bytes) -> tuple[list[bytes], bytes]:
    """:func:`split_frames` for Vectronix: ``>`` ... CR, prompts ``<``/``!`` alone."""
    return split_frames(buffer, start=b">", terminators=b"\r\n", singles=b"<!")


# --------------------------------------------------------------------------

PROTOCOLS: dict[str, ProtocolSpec] = {
    "trupulse": ProtocolSpec(
        name="trupulse",
        description="Laser Technology TruPulse 200/360 ($PLTIT sentences, 4800 baud 8N1)",
        default_baud=4800,
        split=split_trupulse,
        parse=parse_trupulse,
        # $GO fires the laser on TruPulse 360B-class firmware; others ignore it.
        request=b"$GO\r\n",
        request_by_default=False,
        min_request_interval_s=0.0,
    ),
    "vectronix": ProtocolSpec(
        name="vectronix",
        description="Safran Vectronix LRF module (>LM,Md command/response)",
        default_baud=115200,
        split=split_vectronix,
        parse=parse_vectronix,
        request=vectronix_frame("LM,Md,3"),
        request_by_default=True,
        # The integrator manuals require the host to keep requests <= 2 Hz (eye safety).
        min_request_interval_s=0.5,
    ),
}


def get_protocol(name: str) -> ProtocolSpec:
    """The :class:`ProtocolSpec` called ``name``; InputError naming the choices."""
    try:
        return PROTOCOLS[name]
    except KeyError:
        choices = ", ".join(sorted(PROTOCOLS))
        raise InputError(f"unknown rangefinder protocol {name!r} (choose {choices})") from None
