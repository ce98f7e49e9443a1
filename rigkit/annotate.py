"""Targets drawn on preview images: the window, a label with laser and estimated range."""

from __future__ import annotations

import math
from collections.abc import Sequence

import cv2
import numpy as np

from rigkit.capture import Target
from rigkit.capture.comparisons import Comparison

_FONT = cv2.FONT_HERSHEY_SIMPLEX
_WHITE = (255, 255, 255)
_BLACK = (0, 0, 0)


def mark_targets(
    img: np.ndarray,
    full_shape: tuple[int, ...],
    targets: Sequence[Target],
    rows: Sequence[Comparison],
) -> np.ndarray:
    """Copy of a preview ``img`` (BGR uint8, the full-size image shrunk to its width,
    possibly with a scale bar below) with each target's window and a label.

    ``full_shape``: (H, W) of the original left image, whose pixel coordinates the
    targets use. The label reads ``name  laser L m  est E m  +e.ee %``.
    """
    out = img.copy()
    scale = out.shape[1] / full_shape[1]
    by_name = {row.target: row for row in rows}
    size = max(0.45, out.shape[1] / 1800)
    for target in targets:
        centre = (round(target.pixel[0] * scale), round(target.pixel[1] * scale))
        half = max(6, round(target.window_px * scale / 2))
        _box(out, centre, half)
        _label(out, centre, half, _text(target, by_name.get(target.name)), size)
    return out


def _text(target: Target, row: Comparison | None) -> str:
    if row is None:
        return target.name
    parts = [target.name]
    if math.isfinite(row.laser_range_m):
        parts.append(f"laser {row.laser_range_m:.1f} m")
    if math.isfinite(row.estimate_range_m):
        parts.append(f"est {row.estimate_range_m:.1f} m")
    else:
        parts.append("no estimate")
    if math.isfinite(row.error_pct):
        parts.append(f"{row.error_pct:+.2f} %")
    return "  ".join(parts)


def _box(img: np.ndarray, centre: tuple[int, int], half: int) -> None:
    x, y = centre
    for colour, width in ((_BLACK, 3), (_WHITE, 1)):
        cv2.rectangle(img, (x - half, y - half), (x + half, y + half), colour, width,
                      cv2.LINE_AA)


def _label(img: np.ndarray, centre: tuple[int, int], half: int, text: str, size: float
           ) -> None:
    """The text on a dark box beside the target, kept inside the image."""
    (tw, th), base = cv2.getTextSize(text, _FONT, size, 1)
    x = centre[0] + half + 6
    if x + tw + 4 > img.shape[1]:
        x = max(0, centre[0] - half - 6 - tw)
    y = min(max(centre[1] + th // 2, th + 4), img.shape[0] - base - 4)
    overlay = img.copy()
    cv2.rectangle(overlay, (x - 3, y - th - 4), (x + tw + 3, y + base + 2), _BLACK, -1)
    cv2.addWeighted(overlay, 0.6, img, 0.4, 0, dst=img)
    cv2.putText(img, text, (x, y), _FONT, size, _WHITE, 1, cv2.LINE_AA)
