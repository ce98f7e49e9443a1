"""An image file's size as its header declares it, read without decoding the pixels.

A 1 MB PNG can declare 32000x32000 pixels and make a decoder allocate gigabytes; a
header of 60000x60000 makes OpenCV throw. So rigkit reads the size first, from the
PNG ``IHDR`` chunk, the JPEG start-of-frame segment, the first TIFF directory, or a RAW
file's header through LibRaw (which reads it without unpacking the data), and refuses
a frame whose size is not the rig's, or beyond :data:`MAX_FRAME_PIXELS`, before any
decoding (:func:`check_size`, which also checks the decoded size afterwards).
"""

from __future__ import annotations

import struct
from pathlib import Path
from typing import BinaryIO

from rigkit.errors import InputError

MAX_FRAME_PIXELS = 250_000_000
"""The largest frame rigkit decodes, px: above the largest camera sensors (150 MP); a
frame's decoded grey alone takes 4 bytes per pixel, 1 GB here."""

_SOF = frozenset(range(0xC0, 0xD0)) - {0xC4, 0xC8, 0xCC}
"""JPEG start-of-frame markers (not DHT, JPG or DAC, which share the range)."""


def header_size(path: Path) -> tuple[int, int] | None:
    """(width, height) px that a PNG, JPEG or TIFF file's header declares; None for
    another format or a header too damaged to read (the decoder will say why)."""
    try:
        with path.open("rb") as handle:
            head = handle.read(32)
            handle.seek(0)
            if head.startswith(b"\x89PNG\r\n\x1a\n") and head[12:16] == b"IHDR":
                width, height = struct.unpack(">II", head[16:24])
                return width, height
            if head.startswith(b"\xff\xd8"):
                return _jpeg_size(handle)
            if head[:4] in (b"II*\x00", b"MM\x00*"):
                return _tiff_size(handle, "<" if head[:2] == b"II" else ">")
    except (OSError, struct.error):
        return None
    return None


def _jpeg_size(handle: BinaryIO) -> tuple[int, int] | None:
    handle.seek(2)
    while True:
        marker = handle.read(2)
        if len(marker) < 2 or marker[0] != 0xFF:
            return None
        if marker[1] in (0xD8, 0x01) or 0xD0 <= marker[1] <= 0xD7:
            continue  # markers without a length
        (length,) = struct.unpack(">H", handle.read(2))
        if marker[1] in _SOF:
            height, width = struct.unpack(">xHH", handle.read(5))
            return width, height
        handle.seek(length - 2, 1)


def _tiff_size(handle: BinaryIO, order: str) -> tuple[int, int] | None:
    handle.seek(4)
    (offset,) = struct.unpack(order + "I", handle.read(4))
    handle.seek(offset)
    (count,) = struct.unpack(order + "H", handle.read(2))
    found: dict[int, int] = {}
    for _ in range(min(count, 1000)):
        tag, kind, _n, value = struct.unpack(order + "HHI4s", handle.read(12))
        if tag in (256, 257):
            short = kind == 3
            found[tag] = struct.unpack(order + ("H2x" if short else "I"), value)[0]
    if 256 in found and 257 in found:
        return found[256], found[257]
    return None


def check_size(path: Path | str, size: tuple[int, int] | None,
               expected: tuple[int, int] | None, whose: str = "the rig is for") -> None:
    """InputError naming ``path`` when a frame's ``size`` (W, H: declared by its header,
    or decoded) is beyond :data:`MAX_FRAME_PIXELS`, or is not ``expected``; ``whose``
    says whose size that is ("the rig profile p1000 is for", "the left frame a.png
    is"). Nothing when the size is unknown."""
    if size is None:
        return
    width, height = size
    if width * height > MAX_FRAME_PIXELS:
        raise InputError(
            f"{path}: declares {width}x{height} px ({width * height / 1e6:,.0f} MP), beyond "
            f"the {MAX_FRAME_PIXELS / 1e6:.0f} MP rigkit decodes: not a camera frame")
    if expected is not None and size != expected:
        turned = " (turned to portrait?)" if size == expected[::-1] else ""
        raise InputError(
            f"{path}: {width}x{height} px, but {whose} {expected[0]}x{expected[1]} px"
            f"{turned}; all frames of a capture must have the rig's image size")
