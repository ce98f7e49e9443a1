"""Colour-mapped PNG previews of depth and uncertainty maps, with a labelled scale bar."""

from __future__ import annotations

import cv2
import numpy as np

PREVIEW_WIDTH = 1600


def colorize(values: np.ndarray, lo: float, hi: float, label: str) -> np.ndarray:
    """(H, W) float map -> BGR uint8 image (turbo colours, NaN black) with a scale bar.

    The image is shrunk to at most PREVIEW_WIDTH px wide (area average, NaN-aware)."""
    scale = min(1.0, PREVIEW_WIDTH / values.shape[1])
    finite = np.isfinite(values)
    if scale < 1.0:
        size = (round(values.shape[1] * scale), round(values.shape[0] * scale))
        w = cv2.resize(finite.astype(np.float32), size, interpolation=cv2.INTER_AREA)
        s = cv2.resize(
            np.where(finite, values, 0).astype(np.float32), size, interpolation=cv2.INTER_AREA
        )
        with np.errstate(invalid="ignore", divide="ignore"):
            values = np.where(w > 0.5, s / w, np.nan)
        finite = np.isfinite(values)
    span = max(hi - lo, 1e-9)
    norm = np.clip((np.nan_to_num(values, nan=lo) - lo) / span, 0, 1)
    img = cv2.applyColorMap((norm * 255).astype(np.uint8), cv2.COLORMAP_TURBO)
    img[~finite] = 0
    return _with_scale_bar(img, lo, hi, label)


def _with_scale_bar(img: np.ndarray, lo: float, hi: float, label: str) -> np.ndarray:
    h, w = img.shape[:2]
    bar_h = max(40, h // 12)
    ramp = np.tile(np.linspace(0, 255, w).astype(np.uint8), (bar_h // 2, 1))
    bar = np.zeros((bar_h, w, 3), np.uint8)
    bar[: bar_h // 2] = cv2.applyColorMap(ramp, cv2.COLORMAP_TURBO)
    font, size, thick = cv2.FONT_HERSHEY_SIMPLEX, max(0.4, bar_h / 60), 1
    y = bar_h - 6
    cv2.putText(bar, f"{lo:.4g}", (4, y), font, size, (255, 255, 255), thick, cv2.LINE_AA)
    text = f"{hi:.4g}"
    tw = cv2.getTextSize(text, font, size, thick)[0][0]
    cv2.putText(bar, text, (w - tw - 4, y), font, size, (255, 255, 255), thick, cv2.LINE_AA)
    lw = cv2.getTextSize(label, font, size, thick)[0][0]
    cv2.putText(bar, label, ((w - lw) // 2, y), font, size, (255, 255, 255), thick, cv2.LINE_AA)
    return np.vstack([img, bar])


def depth_range(depth: np.ndarray) -> tuple[float, float]:
    """Robust display range (1st-99th percentile) of the finite depths, metres."""
    finite = depth[np.isfinite(depth)]
    if finite.size == 0:
        return 0.0, 1.0
    lo, hi = np.percentile(finite, [1, 99])
    return float(lo), float(hi)
