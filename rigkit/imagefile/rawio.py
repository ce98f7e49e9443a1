"""Reading capture frames, camera RAW included, as grey images for the depth pipeline.

A capture's three frames (left, right, back) are either camera RAW files (NEF, NRW,
DNG, CR2, ARW, ... anything LibRaw reads, through ``rawpy``) or ordinary PNG, TIFF or
JPEG files. :func:`load_linear_grey` reads either kind as (H, W) float32 grey in
[0, 1]; :func:`to_pipeline` converts the three frames together to the pipeline's
float32 [0, 255] scale.

RAW frames are decoded to *linear* data: values proportional to the light on the
sensor, 1.0 at the sensor's white level. Decoding keeps the sensor's pixel grid: the
EXIF Orientation tag is *not* applied (see :func:`decode_raw`), and neither is it for
PNG/TIFF/JPEG frames, so every frame has the size and layout the camera recorded.
That decoded size is the one rigkit checks and reports (:func:`frame_size` gives it
without decoding a RAW file's pixels); EXIF sizes, which in RAW files often describe
a preview, are not used.

Decoding a large RAW file takes seconds, so :func:`load_linear_grey` can keep the
decoded grey image as a 16-bit PNG in a cache folder, named after the file's SHA-256.
"""

from __future__ import annotations

import os
import re
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING

import cv2
import numpy as np

from rigkit.core.chatter import captured_stderr
from rigkit.core.files import encode_png, write_at
from rigkit.core.safefs import open_folder, open_input, read_regular, require_file, too_large
from rigkit.errors import InputError
from rigkit.imagefile.decode import check_decoder_output, decode_grey, read_image_file
from rigkit.imagefile.imagesize import (
    HEAD_BYTES,
    MAX_FRAME_BYTES,
    MAX_FRAME_PIXELS,
    check_size,
    header_size,
)
from rigkit.imagefile.picture import picture_problem

if TYPE_CHECKING:
    import rawpy

# File name suffixes (lower case) of the camera RAW formats LibRaw decodes.
RAW_SUFFIXES: frozenset[str] = frozenset(
    {
        ".3fr",  # Hasselblad
        ".arw",  # Sony
        ".cr2",  # Canon
        ".cr3",  # Canon
        ".crw",  # Canon (old)
        ".dcr",  # Kodak
        ".dng",  # Adobe DNG (Leica, Pentax, Ricoh, phones, converters)
        ".erf",  # Epson
        ".fff",  # Hasselblad / Imacon
        ".gpr",  # GoPro (refused with its own message: LibRaw lacks its VC-5 codec)
        ".iiq",  # Phase One
        ".kdc",  # Kodak
        ".mef",  # Mamiya
        ".mos",  # Leaf
        ".mrw",  # Minolta
        ".nef",  # Nikon
        ".nrw",  # Nikon (compact cameras)
        ".orf",  # Olympus / OM System
        ".pef",  # Pentax
        ".raf",  # Fujifilm
        ".raw",  # Panasonic, Leica
        ".rw2",  # Panasonic
        ".rwl",  # Leica
        ".sr2",  # Sony (old)
        ".srf",  # Sony (old)
        ".srw",  # Samsung
        ".x3f",  # Sigma
    }
)

# Content that is not RAW, though named so: (leading bytes, what it is, its suffix).
_NOT_RAW = ((b"\xff\xd8\xff", "JPEG", ".jpg"), (b"\x89PNG\r\n\x1a\n", "PNG", ".png"))

MIN_RAW_BYTES_PER_PX = 0.05
"""A RAW file holding less than this per sensor pixel has no image data in it. Real
files hold 0.4 (a lossy, reduced DNG) to 2 bytes per pixel; EXIF-only samples with the
image stripped hold 0.001-0.005 (the files in ../shared/data/real-raw, README there)."""

# Rec. 709 / sRGB luminance weights (R, G, B). They give the luminance Y of *linear*
# sRGB-primary data, which is what decode_raw produces.
LUMA_WEIGHTS: tuple[float, float, float] = (0.2126, 0.7152, 0.0722)

# The cache file of a RAW frame is CACHE_DIR / (sha256[:16] + CACHE_SUFFIX). The name
# stands for the decoding settings too: change it if decode_raw's options change.
CACHE_SUFFIX = ".linear.png"

# to_pipeline maps this percentile of the brightest frame to full scale (255).
WHITE_PERCENTILE = 99.9
# Pixels sampled (at most, on a regular grid) to estimate that percentile.
_PERCENTILE_SAMPLES = 1_000_000

_U16_MAX = 65535.0
_SHA256_PREFIX = re.compile(r"[0-9a-fA-F]{16}")


def is_raw(path: str | Path) -> bool:
    """Whether ``path`` names a camera RAW file, judged by its suffix (any case)."""
    return Path(path).suffix.lower() in RAW_SUFFIXES


def decode_raw(path: str | Path, expected: tuple[int, int] | None = None,
               whose: str = "the rig is for") -> np.ndarray:
    """Decode a camera RAW file to linear RGB: (H, W, 3) uint16, 65535 = white level.

    LibRaw settings, and why:

    * linear output: ``gamma=(1, 1)`` and ``no_auto_bright=True`` (no tone curve, no
      histogram-driven brightening), 16 bits per sample. Black level is subtracted and
      the sensor's white level maps to 65535 in the least amplified channel (usually
      green); after white balance the others can clip a little earlier.
    * ``use_camera_wb=True``: the white balance the camera recorded, so the three
      cameras of a rig, set alike, get the same colour-to-grey mapping.
    * ``output_color=sRGB``: linear data in sRGB primaries (the Rec. 709 weights of
      :func:`linear_grey` then give luminance).
    * ``highlight_mode=Clip``: saturated pixels stay white instead of being
      reconstructed (reconstruction is not linear).
    * ``demosaic_algorithm=AHD``: LibRaw's usual choice; it keeps edges sharp, which
      the stereo matcher needs, at a moderate cost.
    * ``user_flip=0``: the EXIF Orientation is *not* applied. The rig's calibration is
      made on the sensor grid, and a camera's orientation sensor can flip its tag on a
      steeply tilted telephoto, which would silently rotate one view of three. The
      output has LibRaw's image size on the sensor grid (masked border pixels, such
      as a DNG ActiveArea margin, are left out; a DNG's DefaultCrop is not applied),
      which is the size rigkit reports and checks for the frame.

    LibRaw reads the full-resolution image wherever the container keeps it (a NEF's or
    DNG's SubIFD), never the small preview in IFD 0. What it prints is captured
    (:mod:`rigkit.core.chatter`) and read: a complaint that the data ends early refuses
    the file.

    The size LibRaw will output is checked before it decodes (against ``expected``
    (W, H), ``whose`` naming it, and the largest frame rigkit decodes:
    :func:`rigkit.imagefile.imagesize.check_size`).

    Raises InputError naming the file when it is missing, not a RAW file LibRaw
    supports (a JPEG or PNG with a RAW file name, a GoPro GPR, an unknown camera), too
    small to hold its image (an EXIF-only or stripped file), of the wrong size,
    truncated or corrupt.
    """
    import rawpy

    path = Path(path)
    require_file(path)
    _check_raw_container(path)
    try:
        with captured_stderr() as chatter, _open_raw(path) as raw:
            _check_holds_image(path, raw.sizes.raw_width * raw.sizes.raw_height)
            check_size(path, (raw.sizes.width, raw.sizes.height), expected, whose)
            rgb = raw.postprocess(
                demosaic_algorithm=rawpy.DemosaicAlgorithm.AHD,
                use_camera_wb=True,
                output_color=rawpy.ColorSpace.sRGB,
                output_bps=16,
                gamma=(1, 1),
                no_auto_bright=True,
                highlight_mode=rawpy.HighlightMode.Clip,
                user_flip=0,
            )
    except rawpy.LibRawError as exc:
        raise InputError(f"{path}: {_libraw_reason(exc)}") from None
    check_decoder_output(path, chatter.text)
    return np.asarray(rgb, dtype=np.uint16)


def _open_raw(path: Path) -> rawpy.RawPy:
    """LibRaw opened on the bytes of the RAW file at ``path``, read with Python's own I/O:
    rawpy would hand a path to C as UTF-8, which a name holding the byte 0xff is not.
    Raises rawpy.LibRawError as rawpy.imread does."""
    import rawpy

    with os.fdopen(open_input(path), "rb") as handle:  # never a FIFO or a device
        size = os.fstat(handle.fileno()).st_size
        if size > MAX_FRAME_BYTES:  # LibRaw would read it whole
            raise too_large(path, size, MAX_FRAME_BYTES, "a frame file")
        return rawpy.imread(handle)


def _check_raw_container(path: Path) -> None:
    """InputError for a file with a RAW name whose content is another format that
    LibRaw would misreport, or a RAW format it cannot decode."""
    with os.fdopen(open_input(path), "rb") as handle:
        head = handle.read(16)
    for signature, kind, suffix in _NOT_RAW:
        if head.startswith(signature):
            raise InputError(
                f"{path}: a {kind} image with a RAW file name ({path.suffix}); rename it to "
                f"{suffix} to use it as an ordinary image"
            )
    if path.suffix.lower() == ".gpr":
        raise InputError(
            f"{path}: GoPro GPR (DNG with VC-5 compression) is not a RAW format LibRaw "
            "decodes; convert it to a plain DNG first (GoPro's gpr_tools)"
        )


def _check_holds_image(path: Path, sensor_px: int) -> None:
    """InputError when the file is far too small for the sensor image it declares: its
    image data was stripped (EXIF-only samples) or it was cut short."""
    size = path.stat().st_size
    if sensor_px > 0 and size < MIN_RAW_BYTES_PER_PX * sensor_px:
        raise InputError(
            f"{path}: {size / 1024:,.0f} KB cannot hold its {sensor_px / 1e6:.1f} MP sensor "
            f"image ({size / sensor_px:.3f} bytes per pixel): the image data is missing "
            "(an EXIF-only or stripped file, or a copy cut short)"
        )


def linear_grey(rgb16: np.ndarray) -> np.ndarray:
    """Linear RGB (H, W, 3) uint16 -> linear luminance (H, W) float32 in [0, 1].

    Y = 0.2126 R + 0.7152 G + 0.0722 B (Rec. 709 weights, right for the linear
    sRGB-primary output of :func:`decode_raw`), 1.0 = 65535 in every channel.
    """
    if rgb16.ndim != 3 or rgb16.shape[2] != 3 or rgb16.dtype != np.uint16:
        raise ValueError(f"expected (H, W, 3) uint16 RGB, got {rgb16.shape} {rgb16.dtype}")
    grey = np.zeros(rgb16.shape[:2], np.float32)
    for channel, weight in enumerate(LUMA_WEIGHTS):
        grey += rgb16[..., channel] * np.float32(weight / _U16_MAX)
    return np.clip(grey, 0.0, 1.0, out=grey)


def load_linear_grey(
    path: str | Path,
    cache_dir: Path | None = None,
    sha256: str | None = None,
    expected: tuple[int, int] | None = None,
    whose: str = "the rig is for",
) -> np.ndarray:
    """Read one frame as (H, W) float32 grey in [0, 1] of full scale.

    RAW files (see :func:`is_raw`) are decoded with :func:`decode_raw` and reduced
    with :func:`linear_grey`: the result is LINEAR in scene light, quantised to 16
    bits. When both ``cache_dir`` and ``sha256`` (the file's SHA-256, hex) are given,
    the result is kept as a 16-bit grey PNG ``cache_dir / (sha256[:16] + ".linear.png")``
    and a later call with the same hash reads it instead of decoding again. The cache
    file is written atomically (a temporary file in ``cache_dir``, then renamed); the
    input file and its folder are never written to (unless that folder is
    ``cache_dir``).

    Other files (PNG, TIFF, JPEG; 8 or 16 bits; grey, colour or with alpha) are read
    with OpenCV, converted to grey and divided by their type's maximum (255 or
    65535). They are NOT linearised: such files are usually gamma-encoded, and the
    pipeline only needs consistent brightness, not linear data. As for RAW files, the
    EXIF Orientation is not applied.

    A freshly decoded frame must hold a picture (:func:`rigkit.imagefile.picture.
    picture_problem`); only such a frame is cached, so a cached one has passed. Its
    size must be ``expected`` (W, H) where given (``whose`` says whose size that is), and
    within the largest frame rigkit decodes: checked on the file's header before it is
    decoded, and on what was decoded (:func:`rigkit.imagefile.imagesize.check_size`). An
    ordinary image whose header cannot be read is refused, not decoded.

    Raises InputError naming the file when it is missing, cannot be decoded, holds no
    picture or has the wrong size, or naming the cache file when it cannot be written.
    """
    path = Path(path)
    if is_raw(path):
        grey = _raw_grey(path, cache_dir, sha256, expected, whose)
    else:
        grey = _with_picture(path, _read_plain_grey(path, expected, whose))
    check_size(path, (grey.shape[1], grey.shape[0]), expected, whose)
    return grey


def _raw_grey(path: Path, cache_dir: Path | None, sha256: str | None,
              expected: tuple[int, int] | None, whose: str) -> np.ndarray:
    """A RAW frame's linear grey, from the cache where it holds it (see
    :func:`load_linear_grey`)."""
    name = _cache_name(sha256) if cache_dir is not None else None
    cached = _read_cache(Path(cache_dir), name, expected) if cache_dir and name else None
    if cached is not None:
        return _from_u16(cached)
    grey16 = _to_u16(linear_grey(decode_raw(path, expected, whose)))
    grey = _with_picture(path, _from_u16(grey16))
    if cache_dir is not None and name is not None:
        _write_cache(Path(cache_dir), name, grey16)
    return grey


def _with_picture(path: Path, grey: np.ndarray) -> np.ndarray:
    """``grey`` when it holds a picture; InputError naming ``path`` and why not."""
    problem = picture_problem(grey)
    if problem is not None:
        raise InputError(f"{path}: no picture: {problem}")
    return grey


def frame_size(path: str | Path) -> tuple[int, int]:
    """(width, height) px of the image :func:`load_linear_grey` decodes from ``path``:
    LibRaw's output size for a RAW file (read from its header, the pixels are not
    decoded), the decoded size of an ordinary image (whose header is checked first, as
    :func:`load_linear_grey` does). InputError as for decoding."""
    import rawpy

    path = Path(path)
    if not is_raw(path):
        grey = _read_plain_grey(path)
        return grey.shape[1], grey.shape[0]
    require_file(path)
    _check_raw_container(path)
    try:
        with captured_stderr(), _open_raw(path) as raw:
            return int(raw.sizes.width), int(raw.sizes.height)
    except rawpy.LibRawError as exc:
        raise InputError(f"{path}: {_libraw_reason(exc)}") from None


def declared_size(path: str | Path) -> tuple[int, int]:
    """(width, height) px of the frame at ``path`` as its header declares it, without
    decoding pixels: LibRaw's output size for a RAW file (:func:`frame_size`), the PNG,
    JPEG or TIFF header's in its first :data:`~rigkit.imagefile.imagesize.HEAD_BYTES`
    for an ordinary image (decoded, as :func:`frame_size` does, where the header is not
    there: a TIFF whose directory follows its pixels). InputError as for decoding."""
    path = Path(path)
    if is_raw(path):
        return frame_size(path)
    with os.fdopen(open_input(path), "rb") as handle:  # never a FIFO or a device
        head = handle.read(HEAD_BYTES)
    try:
        return header_size(path, head)
    except InputError:
        return frame_size(path)


def _scaled_to_255(frame: np.ndarray, overwrite: bool = False) -> np.ndarray:
    out = np.multiply(frame, np.float32(255.0), out=frame if overwrite else None)
    return np.clip(out, 0.0, 255.0, out=out)


def to_pipeline(grey_frames: Sequence[np.ndarray], linear: bool, overwrite: bool = False
                ) -> list[np.ndarray]:
    """Frames (H, W) in [0, 1] -> the pipeline's (H, W) float32 in [0, 255], one scale;
    ``overwrite``: float32 frames (not linear) may be scaled in place, which spares a
    fresh image-sized array each.

    All frames share one scale, so their relative brightness is kept: the rig's
    cameras shoot the same scene with the same settings, and the stereo matcher
    compares intensities between views, so a per-frame stretch (e.g. when one view
    holds a bright sky or a glint) would make the views photometrically inconsistent.

    ``linear=False`` (gamma-encoded PNG/TIFF/JPEG data): just times 255.

    ``linear=True`` (RAW data): the 99.9th percentile of the brightest frame maps to
    1, then the sRGB transfer curve is applied, then times 255, clipped to [0, 255].
    The stereo matcher and the feature matcher cut the images to 8 bits. Linear RAW
    data of a well exposed frame lies mostly in the bottom quarter of the range (the
    camera keeps highlight headroom), which in 8 linear bits leaves shadows a handful
    of levels and flattens their texture. Normalising uses the full 8-bit range, and
    the sRGB curve spreads the levels evenly in perceived brightness, as a camera's
    own JPEG does; its linear toe keeps sensor noise in the deepest shadows from being
    amplified as a pure power law (e.g. a square root) would.
    """
    frames = [np.asarray(frame, dtype=np.float32) for frame in grey_frames]
    if not frames:
        raise ValueError("to_pipeline needs at least one frame")
    if not linear:
        return [_scaled_to_255(frame, overwrite) for frame in frames]
    white = max(_white_point(frame) for frame in frames)
    gain = np.float32(1.0 / white) if white > 0 else np.float32(1.0)
    return [_srgb_encode(np.clip(frame * gain, 0.0, 1.0)) * np.float32(255.0) for frame in frames]


# --- helpers -------------------------------------------------------------------------


def _libraw_reason(exc: Exception) -> str:
    """One line saying why LibRaw failed, for an InputError."""
    import rawpy

    if isinstance(exc, rawpy.LibRawFileUnsupportedError):
        return ("not a RAW file LibRaw can decode (an unsupported format or camera, or a "
                "file cut short)")
    if isinstance(exc, rawpy.LibRawIOError):
        return ("LibRaw cannot read its data: the file is cut short or unreadable (copy it "
                "from the card again)")
    if isinstance(exc, rawpy.LibRawDataError):
        return "its RAW data is damaged (LibRaw: data error)"
    if isinstance(exc, rawpy.LibRawTooBigError):
        return "RAW image too large for LibRaw"
    if isinstance(exc, rawpy.LibRawUnsufficientMemoryError):
        return "not enough memory to decode the RAW file"
    detail = exc.args[0] if exc.args else exc
    if isinstance(detail, bytes):
        detail = detail.decode("ascii", errors="replace")
    return f"LibRaw cannot decode the file ({type(exc).__name__}: {detail})"


def _read_plain_grey(path: Path, expected: tuple[int, int] | None = None,
                     whose: str = "the rig is for") -> np.ndarray:
    """PNG/TIFF/JPEG -> (H, W) float32 in [0, 1] (not linearised, orientation ignored).

    The file is read once; the size its header declares is checked on those bytes
    before they are decoded (:func:`rigkit.imagefile.imagesize.check_size`: the largest
    frame, and ``expected`` (W, H) where given). InputError naming the file when the
    header cannot be read (the file is then not decoded), or as for decoding."""
    data = read_image_file(path)
    check_size(path, header_size(path, data), expected, whose)
    # decode_grey gives [0, 255] for both depths (16-bit divided by 257): scaled in place,
    # since each fresh 16 MP array costs time (0.6 s over a 15-frame burst).
    grey = decode_grey(path, data)
    grey *= np.float32(1.0 / 255.0)
    return grey


def _cache_name(sha256: str | None) -> str | None:
    """The cache file's name for a frame of this SHA-256 (hex), None without one."""
    if sha256 is None:
        return None
    if not _SHA256_PREFIX.match(sha256):
        raise ValueError(f"sha256 must be a hex digest, got {sha256!r}")
    return f"{sha256[:16].lower()}{CACHE_SUFFIX}"


def cache_limit(expected: tuple[int, int] | None) -> int:
    """The largest cache file read for a frame of ``expected`` (W, H) px (None: the
    largest frame), bytes: a 16-bit grey PNG stored without compression (a filter byte
    a row, zlib's and the chunks' framing: under 1 %), and 1 MiB to spare."""
    width, height = expected or (MAX_FRAME_PIXELS, 1)
    return int(height * (1 + 2 * width) * 1.01) + (1 << 20)


def _read_cache(cache_dir: Path, name: str, expected: tuple[int, int] | None
                ) -> np.ndarray | None:
    """The cached (H, W) uint16 grey image ``name`` in ``cache_dir``, or None where
    there is none or no valid one (decoded again, the cache replaced): a link, a FIFO,
    a file larger than :func:`cache_limit` (not read), a header that cannot be read or
    declares another size than ``expected`` or the largest frame (not decoded).
    ``cache_dir`` (a session's ``derived/``) must be a real folder: InputError naming it
    otherwise (:func:`rigkit.core.safefs.open_folder`); the file is read relative to it."""
    try:
        folder = open_folder(cache_dir)
    except FileNotFoundError:
        return None
    try:
        data = read_regular(Path(name), cache_limit(expected), "a RAW cache file",
                            dir_fd=folder)
        shown = cache_dir / name
        check_size(shown, header_size(shown, data), expected)
        img = cv2.imdecode(np.frombuffer(data, np.uint8), cv2.IMREAD_UNCHANGED)
    except (OSError, InputError, cv2.error):
        img = None
    finally:
        os.close(folder)
    if img is None or img.ndim != 2 or img.dtype != np.uint16:
        return None  # damaged or foreign: decode again and overwrite it
    return img


def _write_cache(cache_dir: Path, name: str, grey16: np.ndarray) -> None:
    """Write (H, W) uint16 as the PNG ``name`` in ``cache_dir`` (made if missing; never
    through a link) atomically (:func:`rigkit.core.files.write_at`)."""
    try:
        folder = open_folder(cache_dir, create=True)
        try:
            write_at(folder, name, encode_png(grey16))
        finally:
            os.close(folder)
    except OSError as exc:
        raise InputError(f"{cache_dir / name}: cannot write the RAW cache ({exc})") from None


def _to_u16(grey: np.ndarray) -> np.ndarray:
    """(H, W) float in [0, 1] -> (H, W) uint16, 65535 = 1."""
    return np.rint(np.clip(grey, 0.0, 1.0) * _U16_MAX).astype(np.uint16)


def _from_u16(grey16: np.ndarray) -> np.ndarray:
    """(H, W) uint16 -> (H, W) float32 in [0, 1]."""
    return grey16.astype(np.float32) * np.float32(1.0 / _U16_MAX)


def _white_point(frame: np.ndarray) -> float:
    """WHITE_PERCENTILE of a frame's values, from at most ~_PERCENTILE_SAMPLES pixels."""
    step = max(1, int(np.sqrt(frame.size / _PERCENTILE_SAMPLES)))
    sample = frame[::step, ::step] if frame.ndim == 2 else frame.ravel()[:: step * step]
    return float(np.percentile(sample, WHITE_PERCENTILE))


def _srgb_encode(linear: np.ndarray) -> np.ndarray:
    """sRGB transfer curve (IEC 61966-2-1) on (H, W) float32 values in [0, 1]."""
    linear = np.ascontiguousarray(linear, dtype=np.float32)
    # cv2.pow is many times faster than np.power on large frames.
    encoded: np.ndarray = np.asarray(cv2.pow(linear, 1 / 2.4), dtype=np.float32)
    encoded *= np.float32(1.055)
    encoded -= np.float32(0.055)
    toe = linear <= np.float32(0.0031308)
    encoded[toe] = linear[toe] * np.float32(12.92)
    return encoded
