"""Preview images: colour-mapped depth and uncertainty with a labelled scale bar, the
laser targets drawn on them, and the preview set ``rigkit process`` writes."""

from __future__ import annotations

import math
from collections.abc import Sequence

import cv2
import numpy as np

from rigkit.capture.comparisons import Comparison
from rigkit.capture.model import Target

PREVIEW_WIDTH = 1600
MOVED_TINT = (128, 0, 128)  # BGR added to half the grey where the views disagree


def colorize(values: np.ndarray, lo: float, hi: float, label: str) -> np.ndarray:
    """(H, W) float map -> BGR uint8 image (turbo colours, NaN black) with a scale bar.

    The image is shrunk to at most PREVIEW_WIDTH px wide (area average, NaN-aware)."""
    return _with_scale_bar(colour_map(values, lo, hi), lo, hi, label)


def colour_map(values: np.ndarray, lo: float, hi: float) -> np.ndarray:
    """(H, W) float map -> BGR uint8 image, turbo colours from ``lo`` to ``hi``, NaN
    black, shrunk to at most PREVIEW_WIDTH px wide (area average, NaN-aware)."""
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
    return img


def scale_colours(steps: int) -> list[tuple[int, int, int]]:
    """The colours of :func:`colour_map` at ``steps`` evenly spaced values from its low
    end to its high end, as (R, G, B): for a scale bar drawn in text."""
    ramp = np.linspace(0, 255, steps).astype(np.uint8).reshape(1, -1)
    bgr = cv2.applyColorMap(ramp, cv2.COLORMAP_TURBO)[0]
    return [(int(b[2]), int(b[1]), int(b[0])) for b in bgr]


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
    """Robust display range (1st-99th percentile) of the finite values (depths in
    metres, sigmas in % of depth), so that the colours show the map's structure."""
    finite = depth[np.isfinite(depth)]
    if finite.size == 0:
        return 0.0, 1.0
    lo, hi = np.percentile(finite, [1, 99])
    return float(lo), float(hi)


# --------------------------------------------------------------------------- targets

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


# --------------------------------------------------------------------------- the set


def preview_set(
    left: np.ndarray,
    depth: np.ndarray,
    sigma: np.ndarray,
    targets: Sequence[Target],
    rows: Sequence[Comparison],
    disagree: np.ndarray | None = None,
) -> dict[str, np.ndarray]:
    """What ``rigkit process`` writes to ``results/``: ``depth.png`` and ``left.png``
    with the targets marked, and ``sigma.png`` (1-sigma error in % of depth).

    ``left``: (H, W) grey in [0, 255]; ``depth``, ``sigma``: (H, W) metres;
    ``disagree``: (H, W) bool, where the views disagreed (something moved): tinted
    magenta in ``left.png``."""
    lo, hi = depth_range(depth)
    with np.errstate(invalid="ignore", divide="ignore"):
        relative = 100 * sigma / depth
    grey = np.repeat(np.clip(left, 0, 255).astype(np.uint8)[..., None], 3, axis=2)
    if disagree is not None:
        grey[disagree] = grey[disagree] // 2 + np.array(MOVED_TINT, np.uint8)
    return {
        "depth.png": mark_targets(colorize(depth, lo, hi, "depth z (m)"), depth.shape,
                                  targets, rows),
        "sigma.png": colorize(relative, *depth_range(relative), "1-sigma error (% of depth)"),
        "left.png": mark_targets(_shrink(grey), depth.shape, targets, rows),
    }


def _shrink(img: np.ndarray) -> np.ndarray:
    scale = min(1.0, PREVIEW_WIDTH / img.shape[1])
    if scale == 1.0:
        return img
    size = (round(img.shape[1] * scale), round(img.shape[0] * scale))
    return cv2.resize(img, size, interpolation=cv2.INTER_AREA)
