"""Stage -1: several frames of one camera position stacked into one image.

Heat shimmer moves every isoplanatic patch of the image by a fraction of a pixel, and
frames taken a moment apart see independent shimmer (docs/pipeline.md, "Heat
shimmer"). The per-pixel median of N frames puts each patch near its mean position,
cutting the displacement by ~sqrt(N), and averages the sensor noise. The frames are
first aligned to the first one by a global sub-pixel translation (phase correlation on
a central crop), which is all that a tripod moves between shots of a burst.
"""

from __future__ import annotations

from collections.abc import Sequence

import cv2
import numpy as np

from rigkit.errors import InputError

CROP = 1024  # side of the central crop the shift is measured on, px
MAX_SHIFT_PX = 50.0  # a larger shift is not one tripod position


def stack_burst(frames: Sequence[np.ndarray], what: str = "burst") -> np.ndarray:
    """One (H, W) float32 image from a burst of (H, W) float32 grey frames of one
    position: each aligned to the first, then the per-pixel median. A single frame is
    returned as it is. Raises InputError for frames of different sizes or frames that
    do not show the same view (``what`` names the position in the message)."""
    if len(frames) == 1:
        return frames[0]
    ref = frames[0]
    aligned = [ref]
    for i, frame in enumerate(frames[1:], start=2):
        if frame.shape != ref.shape:
            raise InputError(
                f"{what}: frame {i} is {frame.shape[1]}x{frame.shape[0]}, frame 1 is "
                f"{ref.shape[1]}x{ref.shape[0]}"
            )
        dx, dy = _shift(ref, frame)
        if np.hypot(dx, dy) > MAX_SHIFT_PX:
            raise InputError(
                f"{what}: frame {i} is shifted by ({dx:+.0f}, {dy:+.0f}) px from frame 1; "
                "all frames of a burst must come from one camera position"
            )
        M = np.array([[1.0, 0.0, -dx], [0.0, 1.0, -dy]])
        aligned.append(
            cv2.warpAffine(frame, M, (ref.shape[1], ref.shape[0]), flags=cv2.INTER_CUBIC,
                           borderMode=cv2.BORDER_REPLICATE)
        )
    return np.median(np.stack(aligned), axis=0).astype(np.float32)


def _shift(ref: np.ndarray, frame: np.ndarray) -> tuple[float, float]:
    """(dx, dy) px such that ``frame(x + dx, y + dy) ~ ref(x, y)``."""
    h, w = ref.shape
    side = min(CROP, h, w)
    y0, x0 = (h - side) // 2, (w - side) // 2
    crop = (slice(y0, y0 + side), slice(x0, x0 + side))
    window = cv2.createHanningWindow((side, side), cv2.CV_32F)
    (dx, dy), _ = cv2.phaseCorrelate(
        np.ascontiguousarray(ref[crop], np.float32),
        np.ascontiguousarray(frame[crop], np.float32),
        window,
    )
    return float(dx), float(dy)
