"""Stage 2: dense disparity on the rectified pair.

The default matcher is OpenCV's semi-global matching (Hirschmueller 2008) with
sub-pixel interpolation, a left-right consistency check (the right view's disparity
comes from matching the mirrored pair) and speckle filtering. Any object with the
:class:`StereoMatcher` signature can replace it.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol

import cv2
import numpy as np


class StereoMatcher(Protocol):
    def __call__(
        self, left: np.ndarray, right: np.ndarray, disparity_range: tuple[int, int]
    ) -> np.ndarray:
        """left, right: (H, W) float32 rectified grey images; disparity_range: (lo, hi) px.

        Returns disparity (H, W) float32, px, ``x_left - x_right``, NaN where unknown."""
        ...


@dataclass(frozen=True)
class SGBM:
    """Semi-global block matching with a left-right check (CPU, OpenCV)."""

    block_size: int = 5
    uniqueness: int = 5
    lr_tolerance_px: float = 1.0
    speckle_window: int = 100
    speckle_range_px: int = 2

    def _matcher(self, lo: int, n: int) -> cv2.StereoSGBM:
        b = self.block_size
        return cv2.StereoSGBM_create(  # type: ignore[attr-defined]
            minDisparity=lo,
            numDisparities=n,
            blockSize=b,
            P1=8 * b * b,
            P2=32 * b * b,
            disp12MaxDiff=-1,
            preFilterCap=31,
            uniquenessRatio=self.uniqueness,
            speckleWindowSize=self.speckle_window,
            speckleRange=self.speckle_range_px * 16,
            mode=cv2.STEREO_SGBM_MODE_SGBM_3WAY,
        )

    def __call__(
        self, left: np.ndarray, right: np.ndarray, disparity_range: tuple[int, int]
    ) -> np.ndarray:
        lo, hi = disparity_range
        n = max(16, int(np.ceil((hi - lo) / 16.0)) * 16)
        # SGBM leaves the first lo+n columns unmatched (and the mirrored pass the last
        # ones): pad both images so that band falls outside the picture.
        pad = n + abs(lo)
        l8, r8 = (
            cv2.copyMakeBorder(
                np.clip(np.rint(im), 0, 255).astype(np.uint8), 0, 0, pad, pad, cv2.BORDER_REPLICATE
            )
            for im in (left, right)
        )
        # Right view's disparity: mirroring both images and swapping them keeps the sign
        # of x_left - x_right, so the same matcher applies; mirror the result back.
        matcher = self._matcher(lo, n)
        raw = matcher.compute(l8, r8)[:, pad:-pad]
        raw_r = matcher.compute(r8[:, ::-1].copy(), l8[:, ::-1].copy())[:, ::-1][:, pad:-pad]
        disp = raw.astype(np.float32) / 16.0
        disp_r = raw_r.astype(np.float32) / 16.0
        disp[raw < lo * 16] = np.nan
        disp_r[raw_r < lo * 16] = np.nan
        return _left_right_check(disp, disp_r, self.lr_tolerance_px)


def _at_match(disp: np.ndarray, right_map: np.ndarray, fill: object) -> np.ndarray:
    """``right_map`` (H, W) looked up at each left pixel's match ``(row, x - d)``
    (nearest column); ``fill`` where the disparity is NaN or the match is off the image."""
    h, w = disp.shape
    xr = np.rint(np.arange(w)[None, :] - np.nan_to_num(disp, nan=-1e6)).astype(np.int64)
    inside = (xr >= 0) & (xr < w)
    out = np.full((h, w), fill, dtype=right_map.dtype)
    rows = np.broadcast_to(np.arange(h)[:, None], (h, w))
    out[inside] = right_map[rows[inside], xr[inside]]
    return out


def _left_right_check(disp: np.ndarray, disp_r: np.ndarray, tol: float) -> np.ndarray:
    """Keep left disparities that the right view's disparity confirms within ``tol`` px."""
    with np.errstate(invalid="ignore"):
        ok = np.abs(_at_match(disp, disp_r, np.nan) - disp) <= tol
    return np.where(ok, disp, np.nan).astype(np.float32)


def restrict_to_footprints(
    disp: np.ndarray, left_valid: np.ndarray, right_valid: np.ndarray
) -> np.ndarray:
    """NaN where the left pixel, or its match ``x - d`` in the right image, lies outside
    that image's footprint on the rectified canvas (all (H, W); masks bool)."""
    ok = _at_match(disp, right_valid, False) & left_valid
    return np.where(ok, disp, np.nan).astype(np.float32)


def fill_holes(disp: np.ndarray, max_gap: int) -> tuple[np.ndarray, np.ndarray]:
    """Fill gaps of at most ``max_gap`` px along rows with the farther (smaller-disparity)
    of the two valid neighbours, as Hirschmueller (2008) does for occlusions: a hole
    next to a depth edge belongs to the occluded background. Gaps that touch the image
    border are left NaN (nothing to interpolate from on that side).

    disp: (H, W) float32 with NaN holes. Returns (filled disparity, bool mask of filled).
    """
    h, w = disp.shape
    valid = np.isfinite(disp)
    idx = np.broadcast_to(np.arange(w), (h, w))
    prev_i = np.maximum.accumulate(np.where(valid, idx, -1), axis=1)
    next_i = np.minimum.accumulate(np.where(valid, idx, w)[:, ::-1], axis=1)[:, ::-1]
    gap = next_i - prev_i - 1
    hole = ~valid & (prev_i >= 0) & (next_i < w) & (gap <= max_gap)
    rows = np.broadcast_to(np.arange(h)[:, None], (h, w))
    left_val = disp[rows[hole], prev_i[hole]]
    right_val = disp[rows[hole], next_i[hole]]
    out = disp.copy()
    out[hole] = np.minimum(left_val, right_val)
    return out, hole
