"""The lens: from the pixels a camera recorded to the ideal pinhole pixels the geometry
of the other stages works in, and back.

All three views come from one lens (or identical ones) at one focal length, so one
:class:`Lens` serves them all. Its model is OpenCV's radial-tangential distortion
(:func:`rigkit.geometry.distort`) about the image centre, the same point the
rectification takes as principal point. Without distortion every map is the identity
and costs nothing.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

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
        each (r1 - r0, W) float64 (see :func:`smooth_map`)."""
        w = self.size[0]
        if self.identity:
            return np.meshgrid(np.arange(w, dtype=np.float64), np.arange(r0, r1, dtype=np.float64))
        return smooth_map(self.to_ideal, (0, w), (r0, r1))


def smooth_map(
    fn: Callable[[np.ndarray], np.ndarray], cols: tuple[int, int], rows: tuple[int, int]
) -> tuple[np.ndarray, np.ndarray]:
    """A smooth map of pixels, ``fn``: (N, 2) float64 (u, v) -> (N, 2), at every pixel of
    columns ``cols[0]:cols[1]`` and rows ``rows[0]:rows[1]``: (u, v), each (rows, cols)
    float64. Exact at every ``GRID_STEP``-th pixel and bilinear in between, in float64:
    lens distortion and near-affine homographies bend little within a cell (0.004 px
    at most, measured for lensfun's P1000 profile, which moves the corner by 77 px).
    Far cheaper than ``fn`` at every pixel.
    """
    (c0, c1), (r0, r1) = cols, rows
    gu = np.arange(c0, c1 + GRID_STEP, GRID_STEP, dtype=np.float64)
    gv = np.arange(r0, r1 + GRID_STEP, GRID_STEP, dtype=np.float64)
    knots = np.stack(np.meshgrid(gu, gv), axis=-1)
    shift = fn(knots.reshape(-1, 2)).reshape(knots.shape) - knots
    u = np.arange(c0, c1, dtype=np.float64)
    v = np.arange(r0, r1, dtype=np.float64)
    iu, fu = np.divmod(u - c0, GRID_STEP)
    iv, fv = np.divmod(v - r0, GRID_STEP)
    iu, iv = iu.astype(int), iv.astype(int)
    fu, fv = fu / GRID_STEP, fv[:, None] / GRID_STEP
    out = []
    for k in range(2):  # separably: along each knot row first (small), then down
        g = shift[..., k]
        along = g[:, iu] * (1 - fu) + g[:, iu + 1] * fu
        out.append(along[iv] * (1 - fv) + along[iv + 1] * fv)
    return u[None, :] + out[0], v[:, None] + out[1]
