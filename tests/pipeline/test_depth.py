"""Stage 4's grid and triangulation against direct evaluation of their formulas."""

from __future__ import annotations

import numpy as np

from rigkit.pipeline.depth import left_grid, triangulate_z
from rigkit.pipeline.lens import Lens
from rigkit.pipeline.rectify import apply_homography, scaling


def test_left_grid_is_the_left_homography_of_the_ideal_pixels(result) -> None:
    rect, shape = result.rectification, result.depth.shape
    f = float(rect.K[0, 0])
    corner = np.hypot(*shape) / 2 / f  # normalised radius of the corner
    lens = Lens(f, (shape[1], shape[0]), (0.002 / corner**2, 0.0, 2e-5, 0.0, 0.0))
    scale = 0.5
    for grid_lens in (None, lens):
        rows, xs, ys, uf = next(left_grid(rect, scale, shape, grid_lens))
        vv, uu = np.mgrid[rows, 0 : shape[1]]
        pts = np.stack([uu.ravel(), vv.ravel()], 1).astype(np.float64)
        ideal = (grid_lens or Lens(1.0, (shape[1], shape[0]))).to_ideal(pts)
        assert np.abs(ideal - pts).max() > (0.5 if grid_lens else -1.0)
        full = apply_homography(rect.H_left, ideal)
        small = apply_homography(scaling(scale), full)
        assert np.abs(uf.ravel() - full[:, 0]).max() < 0.002
        assert np.abs(xs.ravel() - small[:, 0]).max() < 0.002
        assert np.abs(ys.ravel() - small[:, 1]).max() < 0.002


def test_triangulation_turns_the_right_ray_by_beta(result) -> None:
    rect = result.rectification
    u = np.linspace(0, 600, 7)
    d = np.linspace(20, 80, 7)
    for beta in (0.0, 3e-4, -2e-3):
        z = triangulate_z(rect, u, d, beta, 2.0)
        f = rect.K[0, 0]
        cx = rect.K[0, 2] + rect.canvas[0, 2]
        a, b = (u - cx) / f, (u - d - rect.shift - cx) / f
        expected = 2.0 / (a - np.tan(np.arctan(b) + beta))
        assert np.allclose(z, np.where(expected > 0, expected, np.nan), rtol=1e-9,
                           equal_nan=True)
