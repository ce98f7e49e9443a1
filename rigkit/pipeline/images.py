"""Reading images for the pipeline: 8/16-bit PNG, TIFF or JPEG, grey or colour."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np

from rigkit.errors import InputError


def load_grey(path: str | Path) -> np.ndarray:
    """Read an image as (H, W) float32 grey in [0, 255] (16-bit input is scaled down).

    Raises InputError naming the file when it is missing or not an image.
    """
    path = Path(path)
    if not path.is_file():
        raise InputError(f"{path}: no such file")
    img = cv2.imread(str(path), cv2.IMREAD_ANYDEPTH | cv2.IMREAD_ANYCOLOR)
    if img is None:
        raise InputError(f"{path}: not a readable image (PNG, TIFF or JPEG expected)")
    return to_grey(img, str(path))


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
    return img.astype(np.float32) * np.float32(scale)
