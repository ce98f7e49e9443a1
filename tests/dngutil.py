"""Writing tiny, real DNG files for the tests (no binary fixtures in the repository).

:func:`write_dng` stores an uncompressed 16-bit Bayer mosaic as a single-IFD DNG that
LibRaw (rawpy) decodes and exifread reads. IFD 0 holds the raw data itself
(NewSubfileType 0, PhotometricInterpretation 32803 = CFA) plus the DNG colour tags
LibRaw needs to build its colour pipeline (DNGVersion, UniqueCameraModel, CFA layout,
BlackLevel, WhiteLevel, ColorMatrix1, CalibrationIlluminant1, AsShotNeutral).

The capture settings go into a real EXIF IFD. tifffile refuses to write the ExifIFD
pointer tag (34665) itself, so the file is written with a placeholder LONG tag numbered
34666 (no tag of IFD 0 lies between the two, so the tag order stays valid), then the
EXIF IFD is appended to the file and the placeholder rewritten into a pointer to it.
exifread reports those tags as ``EXIF ...``, exactly as it does for a camera's file.
"""

from __future__ import annotations

import struct
from collections.abc import Mapping, Sequence
from fractions import Fraction
from pathlib import Path
from typing import Any

import numpy as np
import tifffile

# TIFF field types and their sizes in bytes.
ASCII, SHORT, LONG, RATIONAL, UNDEFINED = 2, 3, 4, 5, 7
_TYPE_SIZE = {ASCII: 1, SHORT: 2, LONG: 4, RATIONAL: 8, UNDEFINED: 1}

# CFAPattern colour codes (TIFF/EP): 0 red, 1 green, 2 blue.
_CFA_CODES = {"R": 0, "G": 1, "B": 2}

EXIF_IFD_POINTER = 34665
_PLACEHOLDER = EXIF_IFD_POINTER + 1  # an unregistered code tifffile will write

# The keys :func:`write_dng` accepts in ``exif`` (named like rigkit.imagefile.exif.ExifInfo fields).
EXIF_KEYS = frozenset(
    {
        "make",
        "model",
        "datetime_original",
        "focal_length_mm",
        "focal_length_35mm_mm",
        "exposure_time_s",
        "f_number",
        "iso",
    }
)

IDENTITY_MATRIX = (1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0)


def write_dng(
    path: str | Path,
    bayer: np.ndarray,
    *,
    pattern: str = "RGGB",
    white_level: int = 4095,
    black_level: int = 0,
    as_shot_neutral: Sequence[float] = (1.0, 1.0, 1.0),
    color_matrix: Sequence[float] = IDENTITY_MATRIX,
    orientation: int = 1,
    exif: Mapping[str, Any] | None = None,
) -> Path:
    """Write ``bayer`` ((H, W) uint16 sensor values, H and W even) as a minimal DNG.

    ``pattern`` names the colours of the top-left 2x2 tile, row by row ("RGGB",
    "BGGR", "GRBG", "GBRG"). ``color_matrix`` is ColorMatrix1 (XYZ -> camera, row
    major); the identity default makes a neutral raw value decode to the same level in
    every output channel. ``as_shot_neutral`` is the camera's white balance as the raw
    (R, G, B) of a neutral surface. ``exif`` maps keys of :data:`EXIF_KEYS` to values;
    make and model go to IFD 0, the rest to the EXIF IFD. Returns ``path``.
    """
    path = Path(path)
    bayer = _checked_mosaic(bayer, white_level)
    exif = dict(exif or {})
    unknown = set(exif) - EXIF_KEYS
    if unknown:
        raise ValueError(f"unknown EXIF keys: {sorted(unknown)}")
    tags = _dng_tags(pattern, white_level, black_level, as_shot_neutral, color_matrix)
    tags += [(274, "H", 1, (orientation,), True)]
    for code, key in ((271, "make"), (272, "model")):
        if exif.get(key):
            tags.append((code, "s", 0, str(exif[key]), True))
    exif_entries = _exif_entries(exif)
    if exif_entries:
        tags.append((_PLACEHOLDER, "I", 1, (0,), True))
    tifffile.imwrite(
        path,
        bayer,
        byteorder="<",
        photometric=32803,
        subfiletype=0,
        extratags=tags,
        metadata=None,
    )
    if exif_entries:
        _append_exif_ifd(path, exif_entries)
    return path


_IFD0_DNG_TAGS = frozenset({50706, 50707, 50708, 50721, 50728, 50778})
"""DNG tags that describe the whole file and live in IFD 0 whatever holds the raw data."""


def write_camera_dng(
    path: str | Path,
    bayer: np.ndarray,
    *,
    thumbnail_size: tuple[int, int] = (160, 120),
    white_level: int = 4095,
    exif: Mapping[str, Any] | None = None,
) -> Path:
    """Write ``bayer`` ((H, W) uint16, RGGB) the way cameras and converters write a DNG
    (and Nikon a NEF): IFD 0 is a small RGB preview (NewSubfileType 1,
    ``thumbnail_size`` (width, height) px, the mosaic shrunk) carrying the file-wide DNG
    tags and EXIF; the raw mosaic is in a SubIFD (NewSubfileType 0). A reader that takes
    IFD 0 for the image gets the preview. Returns ``path``."""
    path = Path(path)
    bayer = _checked_mosaic(bayer, white_level)
    exif = dict(exif or {})
    tags = _dng_tags("RGGB", white_level, 0, (1.0, 1.0, 1.0), IDENTITY_MATRIX)
    file_tags = [t for t in tags if t[0] in _IFD0_DNG_TAGS]
    raw_tags = [t for t in tags if t[0] not in _IFD0_DNG_TAGS]
    for code, key in ((271, "make"), (272, "model")):
        if exif.get(key):
            file_tags.append((code, "s", 0, str(exif[key]), True))
    exif_entries = _exif_entries(exif)
    if exif_entries:
        file_tags.append((_PLACEHOLDER, "I", 1, (0,), True))
    width, height = thumbnail_size
    step_y, step_x = max(1, bayer.shape[0] // height), max(1, bayer.shape[1] // width)
    sampled = bayer[::step_y, ::step_x][:height, :width] * (255.0 / white_level)
    preview = np.repeat(sampled.astype(np.uint8)[..., None], 3, axis=2)
    with tifffile.TiffWriter(path, byteorder="<") as tif:
        tif.write(preview, photometric="rgb", subfiletype=1, subifds=1, extratags=file_tags,
                  metadata=None)
        tif.write(bayer, photometric=32803, subfiletype=0, extratags=raw_tags, metadata=None)
    if exif_entries:
        _append_exif_ifd(path, exif_entries)
    return path


def bayer_from_grey(grey: np.ndarray, white_level: int = 4095, peak: float = 0.8
                    ) -> np.ndarray:
    """A neutral scene's raw mosaic from a gamma-encoded grey image ((H, W) in [0, 255],
    as rendered PNGs hold): the sRGB curve undone, the brightest value at ``peak`` of
    the white level, every photosite the scene's linear value (R = G = B). (H, W) uint16
    with even sides (a last odd row or column is dropped)."""
    g = np.asarray(grey, np.float64)[: grey.shape[0] // 2 * 2, : grey.shape[1] // 2 * 2] / 255
    linear = np.where(g <= 0.04045, g / 12.92, ((g + 0.055) / 1.055) ** 2.4)
    return np.rint(linear / max(linear.max(), 1e-9) * peak * white_level).astype(np.uint16)


def _checked_mosaic(bayer: np.ndarray, white_level: int) -> np.ndarray:
    bayer = np.asarray(bayer)
    if bayer.ndim != 2 or bayer.shape[0] % 2 or bayer.shape[1] % 2:
        raise ValueError(f"Bayer mosaic must be 2D with even sides, got shape {bayer.shape}")
    if bayer.dtype != np.uint16:
        raise ValueError(f"Bayer mosaic must be uint16, got {bayer.dtype}")
    if int(bayer.max(initial=0)) > white_level:
        raise ValueError(f"Bayer values exceed the white level {white_level}")
    return np.ascontiguousarray(bayer)


def _dng_tags(
    pattern: str,
    white_level: int,
    black_level: int,
    as_shot_neutral: Sequence[float],
    color_matrix: Sequence[float],
) -> list[tuple[int, str, int, Any, bool]]:
    """tifffile ``extratags`` for the DNG and CFA tags of IFD 0."""
    if len(pattern) != 4 or set(pattern) - set(_CFA_CODES):
        raise ValueError(f"pattern must be four of R, G, B (e.g. 'RGGB'), got {pattern!r}")
    if len(color_matrix) != 9 or len(as_shot_neutral) != 3:
        raise ValueError("color_matrix needs 9 values and as_shot_neutral 3")
    cfa = bytes(_CFA_CODES[c] for c in pattern)
    return [
        (50706, "B", 4, bytes([1, 4, 0, 0]), True),  # DNGVersion 1.4
        (50707, "B", 4, bytes([1, 1, 0, 0]), True),  # DNGBackwardVersion 1.1
        (50708, "s", 0, "rigkit test camera", True),  # UniqueCameraModel
        (33421, "H", 2, (2, 2), True),  # CFARepeatPatternDim
        (33422, "B", 4, cfa, True),  # CFAPattern
        (50710, "B", 3, bytes([0, 1, 2]), True),  # CFAPlaneColor: R, G, B
        (50711, "H", 1, (1,), True),  # CFALayout: rectangular
        (50714, "I", 1, (black_level,), True),  # BlackLevel
        (50717, "I", 1, (white_level,), True),  # WhiteLevel
        (50721, "2i", 9, _srationals(color_matrix), True),  # ColorMatrix1
        (50728, "2I", 3, _rationals(as_shot_neutral), True),  # AsShotNeutral
        (50778, "H", 1, (21,), True),  # CalibrationIlluminant1: D65
    ]


def _fraction(value: float) -> Fraction:
    return Fraction(value).limit_denominator(1_000_000)


def _rationals(values: Sequence[float]) -> tuple[int, ...]:
    pairs = [_fraction(v) for v in values]
    if any(f < 0 for f in pairs):
        raise ValueError("unsigned rational must not be negative")
    return tuple(n for f in pairs for n in (f.numerator, f.denominator))


def _srationals(values: Sequence[float]) -> tuple[int, ...]:
    return tuple(n for f in map(_fraction, values) for n in (f.numerator, f.denominator))


def _exif_entries(exif: Mapping[str, Any]) -> list[tuple[int, int, int, bytes]]:
    """(tag, type, count, little-endian payload) of the EXIF IFD, sorted by tag."""
    entries: list[tuple[int, int, int, bytes]] = [(36864, UNDEFINED, 4, b"0230")]  # ExifVersion
    rationals = {33434: "exposure_time_s", 33437: "f_number", 37386: "focal_length_mm"}
    for tag, key in rationals.items():
        if exif.get(key) is not None:
            f = _fraction(float(exif[key]))
            entries.append((tag, RATIONAL, 1, struct.pack("<II", f.numerator, f.denominator)))
    for tag, key in ((34855, "iso"), (41989, "focal_length_35mm_mm")):
        if exif.get(key) is not None:
            entries.append((tag, SHORT, 1, struct.pack("<H", int(exif[key]))))
    if exif.get("datetime_original"):
        text = str(exif["datetime_original"]).encode("ascii") + b"\x00"
        entries.append((36867, ASCII, len(text), text))
    return sorted(entries) if len(entries) > 1 else []


def _append_exif_ifd(path: Path, entries: list[tuple[int, int, int, bytes]]) -> None:
    """Append an IFD made of ``entries`` and turn IFD 0's placeholder into an ExifIFD tag."""
    with tifffile.TiffFile(path) as tif:
        page = tif.pages[0]
        assert isinstance(page, tifffile.TiffPage)
        placeholder = page.tags[_PLACEHOLDER]
        entry_at, value_at = placeholder.offset, placeholder.valueoffset
    with path.open("r+b") as handle:
        handle.seek(0, 2)
        start = handle.tell()
        start += start % 2  # IFDs begin on a word boundary
        handle.seek(start)
        handle.write(_ifd_bytes(entries, start))
        handle.seek(entry_at)
        handle.write(struct.pack("<H", EXIF_IFD_POINTER))
        handle.seek(value_at)
        handle.write(struct.pack("<I", start))


def _ifd_bytes(entries: list[tuple[int, int, int, bytes]], start: int) -> bytes:
    """One little-endian IFD placed at file offset ``start``; long values follow it."""
    table = struct.pack("<H", len(entries))
    data = b""
    data_start = start + 2 + 12 * len(entries) + 4
    for tag, kind, count, payload in entries:
        if len(payload) != _TYPE_SIZE[kind] * count:
            raise ValueError(f"tag {tag}: payload size does not match type and count")
        if len(payload) <= 4:
            value = payload.ljust(4, b"\x00")
        else:
            value = struct.pack("<I", data_start + len(data))
            data += payload + b"\x00" * (len(payload) % 2)
        table += struct.pack("<HHI", tag, kind, count) + value
    return table + struct.pack("<I", 0) + data
