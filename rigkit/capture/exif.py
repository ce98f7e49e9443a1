"""Reading the capture settings a frame's EXIF records (JPEG, TIFF and TIFF-based RAW).

:func:`read_exif` returns the few fields rigkit checks a capture against: focal
length (real and 35 mm-equivalent), exposure (time, aperture, ISO) and image size.
It relies on ``exifread``, which reads JPEG, TIFF and TIFF-based RAW containers
(NEF, NRW, DNG, ...), and is imported only when a file is read.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, fields
from pathlib import Path
from typing import Any

from rigkit.errors import InputError

# exifread logs "no EXIF found" as a warning; rigkit reports that itself.
logging.getLogger("exifread").addHandler(logging.NullHandler())


@dataclass(frozen=True)
class ExifInfo:
    """The EXIF fields of one frame; None where the file does not record the field.

    Units: focal lengths in mm, exposure time in seconds, aperture as an f-number,
    image size as (width, height) in pixels as recorded (not rotated by Orientation).
    """

    path: Path
    make: str | None
    model: str | None
    focal_length_mm: float | None
    focal_length_35mm_mm: float | None
    exposure_time_s: float | None
    f_number: float | None
    iso: float | None
    image_size_px: tuple[int, int] | None
    datetime_original: str | None

    @property
    def has_exif(self) -> bool:
        """Whether any field besides the path was found."""
        return any(
            getattr(self, item.name) is not None for item in fields(self) if item.name != "path"
        )


def read_exif(path: str | Path) -> ExifInfo:
    """Read a frame's EXIF; InputError if the file cannot be opened.

    A file without EXIF gives an ExifInfo with every field None (``has_exif`` False).
    """
    import exifread

    path = Path(path)
    try:
        with path.open("rb") as handle:
            tags = exifread.process_file(handle, details=False, extract_thumbnail=False)
    except FileNotFoundError:
        raise InputError(f"{path}: no such image") from None
    except OSError as exc:
        raise InputError(f"{path}: cannot read the image ({exc})") from None
    return ExifInfo(
        path=path,
        make=_text(tags, "Image Make"),
        model=_text(tags, "Image Model"),
        focal_length_mm=_number(tags, "EXIF FocalLength"),
        focal_length_35mm_mm=_number(tags, "EXIF FocalLengthIn35mmFilm"),
        exposure_time_s=_number(tags, "EXIF ExposureTime"),
        f_number=_number(tags, "EXIF FNumber"),
        iso=_number(tags, "EXIF ISOSpeedRatings"),
        image_size_px=_image_size(tags),
        datetime_original=_text(tags, "EXIF DateTimeOriginal"),
    )


def _first_value(tags: dict[str, Any], name: str) -> Any:
    tag = tags.get(name)
    values = getattr(tag, "values", None)
    if isinstance(values, list | tuple):
        return values[0] if values else None
    return values


def _number(tags: dict[str, Any], name: str) -> float | None:
    """A positive numeric tag as float; EXIF writes 0 (or 0/0) for 'unknown'."""
    value = _first_value(tags, name)
    try:
        number = float(value)
    except (TypeError, ValueError, ZeroDivisionError):
        return None
    return number if number > 0 else None


def _text(tags: dict[str, Any], name: str) -> str | None:
    tag = tags.get(name)
    values = getattr(tag, "values", None)
    if isinstance(values, bytes):
        values = values.decode("ascii", errors="replace")
    if not isinstance(values, str):
        return None
    text = values.strip("\x00 ").strip()
    return text or None


def _image_size(tags: dict[str, Any]) -> tuple[int, int] | None:
    """The main image's (width, height): EXIF PixelX/YDimension, else IFD0's own size.

    IFD0's size is used only when IFD0 is the full image: in RAW files it is often a
    reduced preview (NewSubfileType 1).
    """
    size = _size(tags, "EXIF ExifImageWidth", "EXIF ExifImageLength")
    if size is None and not _number(tags, "Image NewSubfileType"):
        size = _size(tags, "Image ImageWidth", "Image ImageLength")
    return size


def _size(tags: dict[str, Any], width_tag: str, height_tag: str) -> tuple[int, int] | None:
    width, height = _number(tags, width_tag), _number(tags, height_tag)
    if width is None or height is None:
        return None
    return int(width), int(height)
