"""An image file's size as its header declares it, read without decoding the pixels.

A 1 MB PNG can declare 32000x32000 pixels and make a decoder allocate gigabytes; a
header of 60000x60000 makes OpenCV throw. So rigkit reads the size first, from the
PNG ``IHDR`` chunk, the JPEG start-of-frame segment, the first directory of a TIFF or
BigTIFF, or a RAW file's header through LibRaw (which reads it without unpacking the
data), and refuses a frame whose size is not the rig's, or beyond
:data:`MAX_FRAME_PIXELS`, before any decoding (:func:`check_size`, which also checks
the decoded size afterwards).

The check fails closed: a file whose header :func:`header_size` cannot read (another
format, a header cut short or damaged, a TIFF directory too long to read or without a
width and height) is refused, never handed to a decoder to find out.
"""

from __future__ import annotations

import os
import re
import struct
from collections.abc import Callable
from pathlib import Path

from rigkit.core.safefs import open_input
from rigkit.errors import InputError

MAX_FRAME_PIXELS = 250_000_000
"""The largest frame rigkit decodes, px: above the largest camera sensors (150 MP); a
frame's decoded grey alone takes 4 bytes per pixel, 1 GB here."""

MAX_TIFF_ENTRIES = 1000
"""The most entries rigkit reads in a TIFF's first directory: a camera's or a
converter's holds well under 100; a longer directory is refused."""

_SOF = frozenset(range(0xC0, 0xD0)) - {0xC4, 0xC8, 0xCC}
"""JPEG start-of-frame markers (not DHT, JPG or DAC, which share the range)."""

_JPEG_NO_LENGTH = frozenset({0x01, *range(0xD0, 0xD9)})
"""JPEG markers without a length field: TEM, RST0-RST7, SOI."""

_NOT_FILL = re.compile(rb"[^\xff]")
"""Any byte but 0xff: where a run of JPEG fill bytes ends."""

_WIDTH, _HEIGHT = 256, 257
"""The TIFF tags ImageWidth and ImageLength."""

_SUBFILE_TYPE, _DNG_VERSION = 254, 50706
"""The TIFF tags NewSubfileType (bit 0: a reduced-resolution copy of another image) and
DNGVersion (the file is a DNG, a camera RAW)."""

_TIFF_SIZE_TYPES = {3: "H", 4: "I", 16: "Q"}
"""TIFF field types a width or height may have (SHORT, LONG, LONG8) and their struct codes."""

_TIFF_LAYOUTS = {42: (4, "I", "H", "HHI4s"), 43: (8, "Q", "Q", "HHQ8s")}
"""Classic TIFF and BigTIFF, by version: where the offset of the first directory lies,
and the struct codes of that offset, of the directory's entry count and of one entry
(tag, type, count, value field)."""


class _Unreadable(Exception):
    """Why a header cannot be read, in words that follow "its <format> header"."""


def header_size(path: Path, data: bytes) -> tuple[int, int]:
    """(width, height) px that the header of a PNG, JPEG or TIFF (classic or BigTIFF)
    file declares; ``data`` is the file's bytes, ``path`` names it in errors.

    Refused with InputError naming ``path`` (the file is then not to be decoded): a file
    of another format, a header cut short or damaged, a JPEG without a frame header
    before its image data, a TIFF whose first directory holds more than
    :data:`MAX_TIFF_ENTRIES` entries or gives no single width and height.
    """
    kind = _format(data)
    if kind is None:
        raise InputError(f"{path}: not a PNG, TIFF or JPEG file by its first bytes (nor a "
                         "RAW file by its name); refused unread")
    try:
        return _PARSERS[kind](data)
    except _Unreadable as exc:
        reason = str(exc)
    except struct.error:
        reason = "is cut short or damaged"
    raise InputError(f"{path}: its {kind} header {reason}; refused unread")


def _format(data: bytes) -> str | None:
    """The file's format by its first bytes (PNG, JPEG, TIFF or BigTIFF); None for another."""
    if data.startswith(b"\x89PNG\r\n\x1a\n"):
        return "PNG"
    if data.startswith(b"\xff\xd8"):
        return "JPEG"
    if data[:4] in (b"II*\x00", b"MM\x00*"):
        return "TIFF"
    if data[:4] in (b"II+\x00", b"MM\x00+"):
        return "BigTIFF"
    return None


def _png_size(data: bytes) -> tuple[int, int]:
    """The size in the ``IHDR`` chunk, which must come first."""
    if data[12:16] != b"IHDR":
        raise _Unreadable("does not begin with its IHDR chunk")
    width, height = struct.unpack_from(">II", data, 16)
    return width, height


def _jpeg_size(data: bytes) -> tuple[int, int]:
    """The size in the first start-of-frame segment, the markers found as libjpeg finds
    them (see :func:`_next_marker`)."""
    at = 2
    while True:
        code, at = _next_marker(data, at)
        if code in _SOF:
            height, width = struct.unpack_from(">HH", data, at + 3)
            return width, height
        if code in (0xD9, 0xDA):
            raise _Unreadable("has no frame header (SOF) before its image data")
        if code not in _JPEG_NO_LENGTH:
            (length,) = struct.unpack_from(">H", data, at)
            if length < 2:
                raise _Unreadable(f"has a segment of length {length}")
            at += length


def _next_marker(data: bytes, at: int) -> tuple[int, int]:
    """(code, offset after it) of the first JPEG marker at or after offset ``at``: as in
    libjpeg, bytes before a 0xff are skipped, so are any number of 0xff fill bytes
    before the code, and 0xff 0x00 (a stuffed zero) is no marker."""
    while True:
        start = data.find(b"\xff", at)
        code = _NOT_FILL.search(data, start) if start >= 0 else None
        if code is None:
            raise _Unreadable("ends before its frame header (SOF)")
        if data[code.start()] != 0:
            return data[code.start()], code.start() + 1
        at = code.start() + 1


def _tiff_size(data: bytes) -> tuple[int, int]:
    """The ImageWidth and ImageLength of the first directory of a classic TIFF or a
    BigTIFF (version 43: 8-byte offsets and entry count, 20-byte entries)."""
    order = "<" if data[:2] == b"II" else ">"
    if data[8:10] == b"CR":  # Canon's CR2 mark after the header
        raise _Unreadable("is a Canon CR2's (a camera RAW): give the file its .cr2 name, "
                          "so that its RAW data is read and not its preview")
    (version,) = struct.unpack_from(order + "H", data, 2)
    offset_at, offset_code, count_code, entry_code = _TIFF_LAYOUTS[version]
    if version == 43 and struct.unpack_from(order + "HH", data, 4) != (8, 0):
        raise _Unreadable("gives an offset size other than 8 bytes")
    (first,) = struct.unpack_from(order + offset_code, data, offset_at)
    (count,) = struct.unpack_from(order + count_code, data, first)
    if count > MAX_TIFF_ENTRIES:
        raise _Unreadable(f"has a first directory of {count:,} entries, over the "
                          f"{MAX_TIFF_ENTRIES:,} rigkit reads")
    entry = struct.Struct(order + entry_code)
    entries = first + struct.calcsize(order + count_code)
    found: dict[int, list[int]] = {_WIDTH: [], _HEIGHT: [], _SUBFILE_TYPE: []}
    for index in range(count):
        tag, kind, n, value = entry.unpack_from(data, entries + index * entry.size)
        if tag == _DNG_VERSION:
            raise _Unreadable("is a DNG's (a camera RAW): give the file its .dng name, so "
                              "that its RAW data is read and not its preview")
        if tag in found:
            found[tag].append(_tiff_value(order, kind, n, value))
    if any(flags & 1 for flags in found[_SUBFILE_TYPE]):  # a camera RAW's thumbnail first
        raise _Unreadable("describes a reduced-resolution preview first (a camera RAW's?): "
                          "give a RAW file its own name (.nef, .cr2, ...), so that its RAW "
                          "data is read and not the preview")
    if len(found[_WIDTH]) != 1 or len(found[_HEIGHT]) != 1:
        raise _Unreadable("gives no single image width and height in its first directory")
    return found[_WIDTH][0], found[_HEIGHT][0]


def _tiff_value(order: str, kind: int, count: int, value: bytes) -> int:
    """The one SHORT, LONG or LONG8 number held in a directory entry's value field."""
    code = _TIFF_SIZE_TYPES.get(kind)
    if code is None or count != 1:
        raise _Unreadable(f"gives a width, height or subfile type as {count} value(s) of "
                          f"type {kind}")
    return int(struct.unpack_from(order + code, value)[0])


_PARSERS: dict[str, Callable[[bytes], tuple[int, int]]] = {
    "PNG": _png_size, "JPEG": _jpeg_size, "TIFF": _tiff_size, "BigTIFF": _tiff_size}


MAX_FRAME_BYTES = 8 * MAX_FRAME_PIXELS
"""The largest frame file rigkit copies, bytes: the largest frame as uncompressed
16-bit RGBA (2 GB)."""
HEAD_BYTES = 1 << 20
"""How much of a file :func:`check_before_copy` reads for its header (1 MiB: a PNG's
comes first, a JPEG's follows its EXIF and ICC segments)."""


def check_before_copy(path: Path, expected: tuple[int, int] | None,
                      whose: str = "the rig is for", raw: bool = False) -> None:
    """InputError naming ``path`` where the file is refused before it is copied into a
    session: larger than :data:`MAX_FRAME_BYTES`, or, for an ordinary image (not
    ``raw``, whose first directory may be a preview's), declaring in its first
    :data:`HEAD_BYTES` a size beyond the largest frame or other than ``expected``. A file
    whose header is not there (a TIFF whose directory follows its pixels) is judged on
    its copy, as every frame is."""
    with os.fdopen(open_input(path), "rb") as handle:  # never a FIFO or a device
        size = os.fstat(handle.fileno()).st_size
        if size > MAX_FRAME_BYTES:
            raise InputError(f"{path}: {size / 2**30:.1f} GB, larger than any frame rigkit "
                             f"takes ({MAX_FRAME_BYTES / 2**30:.0f} GB); refused before "
                             "copying")
        head = b"" if raw else handle.read(HEAD_BYTES)
    if raw:
        return
    try:
        declared = header_size(path, head)
    except InputError:
        return
    check_size(path, declared, expected, whose)


def check_size(path: Path | str, size: tuple[int, int],
               expected: tuple[int, int] | None, whose: str = "the rig is for") -> None:
    """InputError naming ``path`` when a frame's ``size`` (W, H: declared by its header,
    or decoded) is beyond :data:`MAX_FRAME_PIXELS`, or is not ``expected``; ``whose``
    says whose size that is ("the rig profile p1000 is for", "the left frame a.png
    is")."""
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
