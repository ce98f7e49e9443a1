"""Reading the capture settings a frame's EXIF records, from the files cameras write.

:func:`read_exif` returns the few fields rigkit checks a capture against: make and
model, focal length (real and 35 mm-equivalent), exposure (time, aperture, ISO) and
the time it was taken. One reader parses the metadata: ``exifread`` (pure Python,
BSD), imported only when a file is read. It reads JPEG, TIFF and the TIFF-based RAW
formats (NEF, NRW, DNG, CR2, ARW, RW2, ...) directly; for the others rigkit hands it
the TIFF blocks the container carries:

* Minolta MRW: its ``TTW`` block, a TIFF file;
* Canon CR3 (ISO base media file format): the ``CMT1`` (IFD 0) and ``CMT2`` (EXIF IFD)
  boxes inside the ``moov`` box's Canon ``uuid`` box. The walk over the boxes stops at
  the first box that runs past the end of the file, so a file with a damaged preview
  box still gives its EXIF (libexiv2 refuses both CR3 samples in ../shared/data/
  real-raw for that reason; docs/sessions.md, "EXIF").
* a RAW file whose own EXIF is partial or missing (Panasonic RW2 keeps ISO and the
  35 mm focal length only in the JPEG it embeds, Fujifilm RAF all of it) has the
  fields it lacks read from the first embedded JPEG with an EXIF segment.

ISO where the EXIF IFD has none comes from the maker note (Nikon ``ISOSetting``) or
the PanasonicRaw IFD 0 tag 0x0017. The image size is not read from EXIF at all: in RAW
files it often describes a preview, so rigkit takes every size from the decoder
(:func:`rigkit.imagefile.rawio.frame_size`).
"""

from __future__ import annotations

import io
import logging
import os
import struct
from collections.abc import Iterator
from dataclasses import dataclass, fields
from pathlib import Path
from typing import Any, BinaryIO

from rigkit.core.safefs import open_input
from rigkit.errors import InputError

# exifread logs "no EXIF found" and damaged fields as warnings; rigkit reports itself.
logging.getLogger("exifread").addHandler(logging.NullHandler())
logging.getLogger("exifread").propagate = False

_CANON_UUID = bytes.fromhex("85c0b687820f11e08111f4ce462b6a48")
_CR3_BLOCKS = {b"CMT1": "Image", b"CMT2": "EXIF"}
"""CR3 boxes holding a TIFF block, and the IFD each stands for."""
_EMBEDDED_SEARCH = 4 << 20
"""How far into a RAW file to look for an embedded JPEG's EXIF (they sit near the start)."""
_WANTED = {
    "make": ("Image Make",),
    "model": ("Image Model",),
    "focal_length_mm": ("EXIF FocalLength",),
    "focal_length_35mm_mm": ("EXIF FocalLengthIn35mmFilm",),
    "exposure_time_s": ("EXIF ExposureTime",),
    "f_number": ("EXIF FNumber",),
    "iso": ("EXIF ISOSpeedRatings", "MakerNote ISOSetting", "MakerNote ISOSpeedRequested"),
    "datetime_original": ("EXIF DateTimeOriginal", "Image DateTimeOriginal"),
}
"""Each field's exifread tag names, in the order they are tried."""
_PANASONIC_ISO = "Image Tag 0x0017"
"""ISO in the IFD 0 of a Panasonic (or Leica) RW2/RWL file."""


@dataclass(frozen=True)
class ExifInfo:
    """The EXIF fields of one frame; None where the file does not record the field.

    Units: focal lengths in mm, exposure time in seconds, aperture as an f-number.
    """

    path: Path
    make: str | None
    model: str | None
    focal_length_mm: float | None
    focal_length_35mm_mm: float | None
    exposure_time_s: float | None
    f_number: float | None
    iso: float | None
    datetime_original: str | None

    @property
    def has_exif(self) -> bool:
        """Whether any field besides the path was found."""
        return any(
            getattr(self, item.name) is not None for item in fields(self) if item.name != "path"
        )


def read_exif(path: str | Path) -> ExifInfo:
    """Read a frame's EXIF; InputError if the file cannot be opened or is no regular
    file (a FIFO or a device is refused unopened: :func:`rigkit.core.safefs.open_input`).

    A file without EXIF gives an ExifInfo with every field None (``has_exif`` False).
    """
    path = Path(path)
    try:
        with os.fdopen(open_input(path), "rb") as handle:
            tags = _tags(handle)
    except OSError as exc:
        raise InputError(f"{path}: cannot read the image ({exc.strerror or exc})") from None
    values: dict[str, Any] = {}
    for name, candidates in _WANTED.items():
        read = _text if name in ("make", "model", "datetime_original") else _number
        values[name] = next((v for v in map(lambda c: read(tags, c), candidates) if v), None)
    if values["iso"] is None and (values["make"] or "").lower() in ("panasonic", "leica"):
        values["iso"] = _number(tags, _PANASONIC_ISO)
    return ExifInfo(path=path, **values)


def _tags(handle: BinaryIO) -> dict[str, Any]:
    """exifread's tags of the file open in ``handle``, from its container's TIFF blocks
    where it is one exifread cannot open, completed from an embedded JPEG."""
    head = handle.read(12)
    handle.seek(0)
    if head[4:8] == b"ftyp":
        return _cr3_tags(handle)
    if head[:4] == b"\x00MRM":
        return _mrw_tags(handle)
    tags = _process(handle)
    if not head.startswith(b"\xff\xd8\xff") and not all(
        any(c in tags for c in candidates) for candidates in _WANTED.values()
    ):
        handle.seek(0)
        for name, tag in _embedded_jpeg_tags(handle.read(_EMBEDDED_SEARCH)).items():
            tags.setdefault(name, tag)
    return tags


def _process(handle: BinaryIO) -> dict[str, Any]:
    import exifread

    try:
        return dict(exifread.process_file(handle, details=True, extract_thumbnail=False))
    except Exception:  # exifread raises assorted errors on damaged files: no EXIF then
        return {}


def _cr3_tags(handle: BinaryIO) -> dict[str, Any]:
    """Tags from a CR3's CMT boxes, named as exifread names those of a TIFF file."""
    tags: dict[str, Any] = {}
    for kind, block in _cr3_blocks(handle):
        ifd = _CR3_BLOCKS[kind]
        for name, tag in _process(io.BytesIO(block)).items():
            group, _, field = name.partition(" ")
            tags[f"{ifd} {field}" if group == "Image" else name] = tag
    return tags


def _mrw_tags(handle: BinaryIO) -> dict[str, Any]:
    """Tags from a Minolta MRW's ``TTW`` block (a TIFF file within the file)."""
    handle.seek(4)
    end = 8 + struct.unpack(">I", handle.read(4))[0]
    at = 8
    while at + 8 <= end:
        handle.seek(at)
        kind, size = struct.unpack(">4sI", handle.read(8))
        if kind == b"\x00TTW":
            return _process(io.BytesIO(handle.read(size)))
        at += 8 + size
    return {}


def _cr3_blocks(handle: BinaryIO) -> Iterator[tuple[bytes, bytes]]:
    """(box type, TIFF bytes) of the CMT boxes of a CR3 file."""
    end = handle.seek(0, io.SEEK_END)
    for kind, start, stop in _boxes(handle, 0, end):
        if kind != b"moov":
            continue
        for inner, at, until in _boxes(handle, start, stop):
            handle.seek(at)
            if inner != b"uuid" or handle.read(16) != _CANON_UUID:
                continue
            for box, begin, finish in _boxes(handle, at + 16, until):
                if box in _CR3_BLOCKS:
                    handle.seek(begin)
                    yield box, handle.read(finish - begin)


def _boxes(handle: BinaryIO, start: int, end: int) -> Iterator[tuple[bytes, int, int]]:
    """(type, payload start, payload end) of the ISO-BMFF boxes between ``start`` and
    ``end``, stopping at one that is malformed or runs past ``end``."""
    at = start
    while at + 8 <= end:
        handle.seek(at)
        size, kind = struct.unpack(">I4s", handle.read(8))
        header = 8
        if size == 1:
            size, header = struct.unpack(">Q", handle.read(8))[0], 16
        elif size == 0:
            size = end - at
        if size < header or at + size > end:
            return
        yield kind, at + header, at + size
        at += size


def _embedded_jpeg_tags(data: bytes) -> dict[str, Any]:
    """exifread's tags of the first JPEG with an EXIF segment inside ``data``."""
    at = data.find(b"\xff\xd8\xff\xe1")
    while at >= 0:
        if data[at + 6 : at + 10] == b"Exif":
            return _process(io.BytesIO(data[at:]))
        at = data.find(b"\xff\xd8\xff\xe1", at + 1)
    return {}


def _values(tags: dict[str, Any], name: str) -> Any:
    tag = tags.get(name)
    return getattr(tag, "values", None)


def _number(tags: dict[str, Any], name: str) -> float | None:
    """A positive numeric tag as float; EXIF writes 0 (or 0/0) for 'unknown'. Of a list
    (a Nikon ISOSetting is ``[0, 200]``), the last non-zero value."""
    values = _values(tags, name)
    if isinstance(values, list | tuple):
        values = next((v for v in reversed(values) if _positive(v)), None)
    return _positive(values)


def _positive(value: Any) -> float | None:
    try:
        number = float(value)
    except (TypeError, ValueError, ZeroDivisionError):
        return None
    return number if number > 0 else None


def _text(tags: dict[str, Any], name: str) -> str | None:
    values = _values(tags, name)
    if isinstance(values, bytes):
        values = values.decode("ascii", errors="replace")
    if not isinstance(values, str):
        return None
    text = values.strip("\x00 ").strip()
    return text or None
