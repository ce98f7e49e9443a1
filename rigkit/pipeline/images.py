"""Reading images for the pipeline: 8/16-bit PNG, TIFF or JPEG, grey or colour."""

from __future__ import annotations

import re
from pathlib import Path

import cv2
import numpy as np

from rigkit.core.chatter import captured_stderr
from rigkit.errors import InputError

_CUT_SHORT = re.compile(r"premature end|unexpected end|data corrupted|read error", re.IGNORECASE)
"""What libjpeg ("Premature end of JPEG file"), LibRaw ("Unexpected end of file", "data
corrupted at 1378") and libtiff ("Read error on strip") print when a file ends early or
its data is damaged: the decoders fill in what is missing (grey rows, a grey block) and
carry on. libjpeg's "extraneous bytes before marker" is harmless and not matched."""


def load_grey(path: str | Path) -> np.ndarray:
    """Read an image as (H, W) float32 grey in [0, 255] (16-bit input is scaled down),
    on the pixel grid the file stores (an EXIF Orientation tag is not applied).

    Raises InputError naming the file when it is missing, not an image, or cut short
    (its decoder complained and filled in the rest).
    """
    path = Path(path)
    if not path.is_file():
        raise InputError(f"{path}: no such file")
    flags = cv2.IMREAD_ANYDEPTH | cv2.IMREAD_ANYCOLOR | cv2.IMREAD_IGNORE_ORIENTATION
    with captured_stderr() as chatter:
        img = cv2.imread(str(path), flags)
    check_decoder_output(path, chatter.text)
    if img is None:
        raise InputError(f"{path}: not a readable image (RAW, PNG, TIFF or JPEG expected)")
    if img.dtype not in (np.uint8, np.uint16):
        raise InputError(f"{path}: {img.dtype} samples (8- or 16-bit integer expected)")
    return to_grey(img, str(path))


def check_decoder_output(path: Path, printed: str) -> None:
    """InputError when what a decoder printed while reading ``path`` says the file ends
    early or is damaged: the picture it returned is partly made up."""
    complaint = next((line.strip() for line in printed.splitlines()
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
