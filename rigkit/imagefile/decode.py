"""Reading images for the pipeline: 8/16-bit PNG, TIFF or JPEG, grey or colour."""

from __future__ import annotations

import re
from pathlib import Path

import cv2
import numpy as np

from rigkit.core.chatter import attributed, captured_stderr
from rigkit.core.safefs import read_input
from rigkit.errors import InputError
from rigkit.imagefile.imagesize import MAX_FRAME_BYTES

_CUT_SHORT = re.compile(r"premature end|unexpected end|data corrupted|read error|"
                        r"input buffer is incomplete", re.IGNORECASE)
"""What libjpeg ("Premature end of JPEG file"), LibRaw ("Unexpected end of file", "data
corrupted at 1378"), libtiff ("Read error on strip") and libpng reading from memory
("PNG input buffer is incomplete") print when a file ends early or its data is damaged:
the decoders fill in what is missing (grey rows, a grey block) and carry on, or give
up. libjpeg's "extraneous bytes before marker" is harmless and not matched."""

_FLAGS = cv2.IMREAD_ANYDEPTH | cv2.IMREAD_ANYCOLOR | cv2.IMREAD_IGNORE_ORIENTATION
"""OpenCV decodes any depth and colour as stored, the EXIF Orientation not applied."""

_JPEG_EOI = b"\xff\xd9"
"""The JPEG end-of-image marker."""


def load_grey(path: str | Path) -> np.ndarray:
    """Read an image as (H, W) float32 grey in [0, 255] (16-bit input is scaled down),
    on the pixel grid the file stores (an EXIF Orientation tag is not applied).

    Raises InputError naming the file when it is missing, not an image OpenCV decodes,
    or cut short (its decoder complained and filled in the rest, or gave up).
    """
    path = Path(path)
    return decode_grey(path, read_image_file(path))


def read_image_file(path: Path) -> bytes:
    """The bytes of the file at ``path``, read with Python's own I/O, so that no file name
    reaches OpenCV's C++ (a name that is not UTF-8, such as one holding the byte 0xff,
    crashes its imread). InputError naming the file when it is missing, not a regular
    file (a FIFO or a device is refused unopened) or larger than
    :data:`rigkit.imagefile.imagesize.MAX_FRAME_BYTES` (unread)."""
    return read_input(path, MAX_FRAME_BYTES, "an image file")


def decode_grey(path: Path, data: bytes) -> np.ndarray:
    """``data``, the bytes of the image file ``path``, decoded by OpenCV as
    :func:`load_grey` does; ``path`` only names the file in errors.

    Refused with InputError naming the file: what OpenCV cannot decode or will not (an
    image beyond the size its decoders accept, a width or height over 2^20 px), a file
    cut short or damaged, samples other than 8- or 16-bit integers.
    """
    img = _decode(path, data)
    if img.dtype not in (np.uint8, np.uint16):
        raise InputError(f"{path}: {img.dtype} samples (8- or 16-bit integer expected)")
    return to_grey(img, str(path))


def _decode(path: Path, data: bytes) -> np.ndarray:
    """OpenCV's image of ``data`` as stored; InputError naming ``path`` where it has
    none, refuses the file, or prints that the file is cut short or damaged."""
    try:  # alongside other frames' decoding (rigkit.core.chatter.attributed)
        img, printed = attributed(lambda: cv2.imdecode(np.frombuffer(data, np.uint8), _FLAGS),
                                  lambda text: _CUT_SHORT.search(text) is not None)
    except cv2.error as exc:
        raise InputError(f"{path}: not a readable image (OpenCV refuses it: {exc.err})"
                         ) from None
    check_decoder_output(path, printed)
    if img is not None:
        return img
    if _jpeg_cut_short(data):
        raise InputError(f"{path}: the file is cut short or damaged (its JPEG data stops "
                         "before the image ends: Premature end of JPEG file): copy it from "
                         "the card again")
    raise InputError(f"{path}: not a readable image (RAW, PNG, TIFF or JPEG expected)")


def _jpeg_cut_short(data: bytes) -> bool:
    """Whether ``data``, which OpenCV could not decode, is a JPEG cut short. Reading
    from memory, libjpeg gives up where the data stops; reading a file, it says
    "Premature end of JPEG file" and ends the image there. So a JPEG that decodes once
    an end-of-image marker is put after its bytes was cut short."""
    if not data.startswith(b"\xff\xd8"):
        return False
    try:
        with captured_stderr():
            return cv2.imdecode(np.frombuffer(data + _JPEG_EOI, np.uint8), _FLAGS) is not None
    except cv2.error:
        return False


_OPENCV_LOG = re.compile(r"^\s*\[\s*[A-Z]+:\d+@[\d.]+\]\s+(global\s+)?\S+:\d+\s+\S+\s+")
"""The place OpenCV's log puts before its message ("[ WARN:0@0.108] global
grfmt_png.cpp:793 readFromStreamOrBuffer "): not for the user."""


def check_decoder_output(path: Path, printed: str) -> None:
    """InputError when what a decoder printed while reading ``path`` says the file ends
    early or is damaged: the picture it returned is partly made up."""
    complaint = next((_OPENCV_LOG.sub("", line).strip() for line in printed.splitlines()
                      if _CUT_SHORT.search(line)), None)
    if complaint is not None:
        raise InputError(
            f"{path}: the file is cut short or damaged (its decoder reports "
            f"{complaint[:80]!r}): copy it from the card again"
        )


def to_grey(img: np.ndarray, name: str = "image") -> np.ndarray:
    """Array (H, W) or (H, W, 3|4), uint8/uint16/float -> (H, W) float32 in [0, 255]."""
    if img.ndim == 3:
        if img.shape[2] == 4:
            img = img[..., :3]
        if img.shape[2] != 3:
            raise InputError(f"{name}: {img.shape[2]} channels (1, 3 or 4 expected)")
        img = cv2.cvtColor(img, cv2.COLOR_BGR2GRAY) if img.dtype != np.float64 else img.mean(-1)
    elif img.ndim != 2:
        raise InputError(f"{name}: not a 2D image (shape {img.shape})")
    scale = {np.dtype(np.uint8): 1.0, np.dtype(np.uint16): 1.0 / 257.0}.get(img.dtype, 1.0)
    out = img.astype(np.float32)  # a copy: scaled in place (a 16 MP array is ~0.05 s)
    if scale != 1.0:
        out *= np.float32(scale)
    return out
