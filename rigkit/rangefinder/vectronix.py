"""Safran Vectronix LRF modules: ``>LM,...*CS<CR>`` command/response (LRF
6019/6042/6742/7047 integrator manuals). The host must *request* each range; the module
acknowledges, answers with up to five targets in centimetres and ends with a
one-character prompt; additive checksum (see ``docs/rangefinder.md``)."""

from __future__ import annotations

from rigkit.rangefinder.framing import (
    FrameError,
    Notice,
    Reading,
    ascii_text,
    check_range,
    short,
    split_checksum,
    split_frames,
)

VECTRONIX_NACK = {
    "0": "message checksum error",
    "1": "message not supported",
    "2": "invalid parameter",
    "3": "parity error",
    "4": "receive overflow",
    "5": "other error",
}
"""Meaning of the error id in a Vectronix ``>NA,<id>`` not-acknowledge frame."""

VECTRONIX_MAX_RANGE_M = 25_000.0
"""Longer than any Vectronix LRF module measures (their range fields hold up to 99,999.99
m); a longer reading is a garbled frame."""
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
    text = ascii_text(frame)
    if text == "<":
        return Notice(kind="prompt", fields=(), raw=frame)
    if text == "!":
        return Notice(kind="prompt", fields=(), raw=frame, error="the module reported a failure")
    fields = split_checksum(text, ">", additive_checksum).split(",")
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
        raise FrameError(f"range response without ranges: {short(text)!r}")
    ranges: list[float] = []
    codes: list[str] = []
    for value in values:
        if len(value) != 8 or value[0] not in "vRT":
            raise FrameError(f"malformed range field {value!r} in {short(text)!r}")
        if value[0] == "v":
            if not (value[1:].isascii() and value[1:].isdigit()):
                raise FrameError(f"range {value!r} is not a number of centimetres")
            ranges.append(check_range(int(value[1:]) / 100.0, VECTRONIX_MAX_RANGE_M,
                                      "Vectronix range"))
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
