"""What every rangefinder protocol shares: the reading and notice types, the errors,
and cutting a byte stream into frames. Pure functions of bytes: nothing here touches a
port or a clock. The protocols themselves are :mod:`rigkit.rangefinder.trupulse` and
:mod:`rigkit.rangefinder.vectronix`, registered in :mod:`rigkit.rangefinder.protocols`.

Conventions: distances in metres, angles in degrees, inclination positive above the
horizontal, azimuth clockwise from north as the device reports it.
"""

from __future__ import annotations

import re
from collections.abc import Callable
from dataclasses import dataclass
from datetime import UTC, datetime

from rigkit.errors import RigkitError

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
    ``azimuth_deg`` is the device's compass bearing in degrees in [0, 360), ``None`` when
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
    max_range_m: float
    """The longest range the device family measures, m: a reading beyond it is a
    garbled sentence, refused by the parser."""


_DECIMAL = re.compile(r"[+-]?[0-9]+(\.[0-9]+)?")


def parse_decimal(text: str, what: str) -> float:
    """A number written as devices and people write one: digits with an optional sign
    and decimals. Python's ``float`` also takes "1e300", "3_0_2.00", "inf" and "nan",
    which no rangefinder sends: FrameError naming ``what`` for those."""
    if not _DECIMAL.fullmatch(text.strip()):
        raise FrameError(f"{what} {text!r} is not a number in digits (such as 312.40)")
    return float(text)


MIN_RANGE_M = 0.5
"""The shortest range taken as a reading, m: below any laser rangefinder's minimum, and
far below any range rigkit measures; shorter values are typos or corrupt frames."""


def check_range(distance_m: float, max_range_m: float, what: str) -> float:
    """``distance_m`` when it is a range the device can measure (MIN_RANGE_M <= r <= max);
    a FrameError naming ``what`` otherwise."""
    if not MIN_RANGE_M <= distance_m <= max_range_m:
        raise FrameError(f"{what} {distance_m:g} m is beyond the device's "
                         f"{MIN_RANGE_M:g}-{max_range_m:g} m")
    return distance_m


def escape_bytes(data: bytes) -> str:
    """ASCII text for bytes, with ``\\r``, ``\\n`` and ``\\xNN`` escapes (lossless)."""
    return repr(bytes(data))[2:-1]


def ascii_text(frame: bytes) -> str:
    try:
        return frame.decode("ascii").strip()
    except UnicodeDecodeError:
        raise FrameError(f"non-ASCII bytes in frame {escape_bytes(frame[:60])}") from None


def short(text: str) -> str:
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


def split_checksum(text: str, lead: str, checksum: Callable[[bytes], int]) -> str:
    """Check ``lead``...``*HH`` framing and the checksum; return the body."""
    if not text.startswith(lead):
        raise FrameError(f"not a frame (no leading {lead!r}): {short(text)!r}")
    star = text.rfind("*")
    if star == -1:
        raise FrameError(f"frame without checksum: {short(text)!r}")
    body, given = text[1:star], text[star + 1 :]
    if len(given) != 2 or any(c not in "0123456789abcdefABCDEF" for c in given):
        raise FrameError(f"malformed checksum {given!r} in {short(text)!r}")
    expected = checksum(body.encode("ascii"))
    if int(given, 16) != expected:
        raise ChecksumError(
            f"bad checksum {given.upper()} (computed {expected:02X}) in {short(text)!r}"
        )
    return body
