"""The lens: from the pixels a camera recorded to the ideal pinhole pixels the geometry
of the other stages works in, and back.

All three views come from one lens (or identical ones) at one focal length, so they
share its distortion terms. Its model is OpenCV's radial-tangential distortion
(:func:`rigkit.geometry.distort`) about the view's principal point: the image centre,
which the rectification takes as principal point, unless a ``shift`` says where that
view's sits (three cameras are not centred alike; fitted from the views, see
:mod:`rigkit.pipeline.distortion`). Without distortion every map is the identity and
costs nothing.
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
    OpenCV ``k1, k2, p1, p2, k3`` on normalised coordinates about :attr:`centre`;
    ``shift``: (x, y) px from the image centre to this view's principal point, the
    centre of its distortion. The ideal pixels are those of a pinhole camera whose
    principal point is the image centre, as the later stages take every view's to
    be: a view's shift is taken out with its bend."""

    focal_px: float
    size: tuple[int, int]
    distortion: Distortion = NO_DISTORTION
    shift: tuple[float, float] = (0.0, 0.0)

    @property
    def identity(self) -> bool:
        return self.distortion == NO_DISTORTION and self.shift == (0.0, 0.0)

    @property
    def pinhole(self) -> bool:
        """No bend: the maps are at most a translation by ``shift``."""
        return self.distortion == NO_DISTORTION

    @property
    def image_centre(self) -> np.ndarray:
        """(2,) px: the centre of the recorded image, the ideal pixels' principal point."""
        return np.array([(self.size[0] - 1) / 2, (self.size[1] - 1) / 2])

    @property
    def centre(self) -> np.ndarray:
        """(2,) px: the centre of the distortion, the image centre plus ``shift``."""
        return self.image_centre + np.array(self.shift)

    def to_ideal(self, pts: np.ndarray) -> np.ndarray:
        """Recorded pixels (N, 2) float64 (u, v) -> ideal pinhole pixels (N, 2)."""
        if self.pinhole:
            return pts if self.identity else pts - np.array(self.shift)
        n = (pts - self.centre) / self.focal_px
        x, y = undistort(n[:, 0], n[:, 1], self.distortion)
        return np.stack([x, y], axis=1) * self.focal_px + self.image_centre

    def to_recorded(self, pts: np.ndarray) -> np.ndarray:
        """Ideal pinhole pixels (..., 2) float64 -> recorded pixels (..., 2)."""
        if self.pinhole:
            return pts if self.identity else pts + np.array(self.shift)
        n = (pts - self.image_centre) / self.focal_px
        x, y = distort(n[..., 0], n[..., 1], self.distortion)
        return np.stack([x, y], axis=-1) * self.focal_px + self.centre

    def rays(self, pts: np.ndarray) -> np.ndarray:
        """The back-projection of recorded pixels (N, 2) float64 (u, v), pixel centres at
        integers: (N, 3) float64 rays in the camera frame (x right, y down, z forward)
        with unit z, so that the point at depth z on pixel (u, v) is ``z * ray``. Through
        the lens: undistorted, then the ideal pinhole's principal point (the image
        centre) and focal length."""
        ideal = (self.to_ideal(np.asarray(pts, np.float64).reshape(-1, 2))
                 - self.image_centre) / self.focal_px
        return np.column_stack([ideal, np.ones(len(ideal))])

    def ray_rows(self, r0: int, r1: int) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`rays` of every pixel of rows ``r0:r1``: their x and y (z is 1), float64,
        broadcastable to (r1 - r0, W). Through :meth:`ideal_rows` with its knots on
        absolute multiples of ``GRID_STEP`` rows, so that a row's rays are the same bits
        whichever block of rows it is computed in (exact at the knots, bilinear in
        between: 0.004 px at most, see :func:`smooth_map`)."""
        top = r0 - r0 % GRID_STEP
        u, v = self.ideal_rows(top, r1)
        if u.shape[0] > 1:  # a bent lens: every pixel's own u (else one row for all)
            u = u[r0 - top:]
        centre = self.image_centre
        return (u - centre[0]) / self.focal_px, (v[r0 - top:] - centre[1]) / self.focal_px

    def ideal_rows(self, r0: int, r1: int) -> tuple[np.ndarray, np.ndarray]:
        """Ideal positions of the recorded pixels of rows ``r0:r1``, all columns: (u, v),
        float64, broadcastable to (r1 - r0, W) (see :func:`smooth_map`). Without
        distortion they are the pixel indices themselves less the shift, a (1, W) row of
        u and a (r1 - r0, 1) column of v, so that callers do per-pixel work only where
        needed."""
        w = self.size[0]
        if self.pinhole:
            u, v = np.arange(w, dtype=np.float64), np.arange(r0, r1, dtype=np.float64)
            return u[None, :] - self.shift[0], v[:, None] - self.shift[1]
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
    mapped = fn(knots.reshape(-1, 2)).reshape(knots.shape)
    iu, fu = np.divmod(np.arange(c1 - c0, dtype=np.float64), GRID_STEP)
    iu, fu = iu.astype(int), fu / GRID_STEP
    fv = np.arange(GRID_STEP, dtype=np.float64)[None, :, None] / GRID_STEP
    out = []
    for k in range(2):  # along each knot row first (small), then every cell's rows at once
        g = mapped[..., k]
        along = g[:, iu] * (1 - fu) + g[:, iu + 1] * fu  # (knot rows, columns)
        dense = np.empty((len(along) - 1, GRID_STEP, c1 - c0))  # C order, so that
        np.multiply((along[1:] - along[:-1])[:, None, :], fv, out=dense)  # reshape is a view
        dense += along[:-1, None, :]
        out.append(dense.reshape(-1, c1 - c0)[: r1 - r0])
    return out[0], out[1]
