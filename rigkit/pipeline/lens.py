"""The lens: from the pixels a camera recorded to the ideal pinhole pixels the geometry
of the other stages works in, and back.

All three views come from one lens (or identical ones) at one focal length, so one
:class:`Lens` serves them all. Its model is OpenCV's radial-tangential distortion
(:func:`rigkit.geometry.distort`) about the image centre, the same point the
rectification takes as principal point. Without distortion every map is the identity
and costs nothing.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from rigkit.geometry import NO_DISTORTION, Distortion, distort, undistort

GRID_STEP = 16  # px between the exact samples of a dense map (bilinear in between)


@dataclass(frozen=True)
class Lens:
    """``focal_px``: f (px); ``size``: (W, H) of the recorded images; ``distortion``:
    OpenCV ``k1, k2, p1, p2, k3`` on normalised coordinates about the image centre."""

    focal_px: float
    size: tuple[int, int]
    distortion: Distortion = NO_DISTORTION

    @property
    def identity(self) -> bool:
        return self.distortion == NO_DISTORTION

    @property
    def centre(self) -> np.ndarray:
        return np.array([(self.size[0] - 1) / 2, (self.size[1] - 1) / 2])

    def to_ideal(self, pts: np.ndarray) -> np.ndarray:
        """Recorded pixels (N, 2) float64 (u, v) -> ideal pinhole pixels (N, 2)."""
        if self.identity:
            return pts
        n = (pts - self.centre) / self.focal_px
        x, y = undistort(n[:, 0], n[:, 1], self.distortion)
        return np.stack([x, y], axis=1) * self.focal_px + self.centre

    def to_recorded(self, pts: np.ndarray) -> np.ndarray:
        """Ideal pinhole pixels (..., 2) float64 -> recorded pixels (..., 2)."""
        if self.identity:
            return pts
        n = (pts - self.centre) / self.focal_px
        x, y = distort(n[..., 0], n[..., 1], self.distortion)
        return np.stack([x, y], axis=-1) * self.focal_px + self.centre

    def ideal_rows(self, r0: int, r1: int) -> tuple[np.ndarray, np.ndarray]:
        """Ideal positions of the recorded pixels of rows ``r0:r1``, all columns: (u, v),
        each (r1 - r0, W) float64. Exact at every ``GRID_STEP``-th pixel and bilinear in
        between (the distortion is a low-order polynomial: < 1e-4 px off)."""
        w = self.size[0]
        uu, vv = np.meshgrid(np.arange(w, dtype=np.float64), np.arange(r0, r1, dtype=np.float64))
        if self.identity:
            return uu, vv
        gu = np.arange(0, w + GRID_STEP, GRID_STEP, dtype=np.float64)
        gv = np.arange(r0, r1 + GRID_STEP, GRID_STEP, dtype=np.float64)
        cu, cv = np.meshgrid(gu, gv)
        grid = np.stack([cu, cv], axis=-1)
        shift = (self.to_ideal(grid.reshape(-1, 2)).reshape(grid.shape) - grid).astype(np.float32)
        mx = (uu / GRID_STEP).astype(np.float32)
        my = ((vv - r0) / GRID_STEP).astype(np.float32)
        d = cv2.remap(shift, mx, my, cv2.INTER_LINEAR)
        return uu + d[..., 0], vv + d[..., 1]
