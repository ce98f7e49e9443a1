"""The paper's section 4 as written: affine pseudo-rectification and the pair-median
ambiguity removal, from matches with known geometry."""

from __future__ import annotations

import numpy as np

from rigkit.experiments.common import RectifiedPair, apply_h
from rigkit.experiments.paper import (
    PaperSettings,
    affine_rows_ransac,
    affine_warps,
    depth_from_offset,
    pair_median_offset,
)
from rigkit.pipeline.features import Matches


def _affine_matches(rng, n=500, outliers=50):
    """Left pixels and right pixels related by a rotation + shift and a horizontal
    parallax (what a distant scene gives); some matches corrupted."""
    pl = rng.uniform([0, 0], [1152, 864], (n, 2))
    a = np.radians(2.0)
    A = np.array([[np.cos(a), -np.sin(a)], [np.sin(a), np.cos(a)]])
    pr = pl @ A.T + [30.0, -12.0]
    pr[:, 0] -= rng.uniform(60, 80, n) * np.cos(a)  # parallax along the baseline
    bad = rng.choice(n, outliers, replace=False)
    pr[bad, 1] += rng.uniform(10, 30, outliers)
    return pl, pr, bad


def test_ransac_rows_align_inliers_and_reject_outliers():
    rng = np.random.default_rng(0)
    pl, pr, bad = _affine_matches(rng)
    rows, inl = affine_rows_ransac(pl, pr, PaperSettings(trials=300), rng)
    assert not inl[bad].any() and inl.sum() == len(pl) - len(bad)
    H_l, H_r = affine_warps(rows)
    assert np.allclose(H_l[:2, :2] @ H_l[:2, :2].T, np.eye(2))  # the left warp is rigid
    good = np.setdiff1d(np.arange(len(pl)), bad)
    dy = apply_h(H_l, pl[good])[:, 1] - apply_h(H_r, pr[good])[:, 1]
    assert np.max(np.abs(dy)) < 2.0


def test_pair_median_offset_recovers_the_offset_on_a_fronto_parallel_plane():
    # A plane at z = 300 m, f = 10000 px, C_lr = C_lb = 2 m: true disparity 66.67 px;
    # the map reads 20 px less, so q = 20 px. Back view: the scene 300/302 as large.
    rng = np.random.default_rng(1)
    f, z = 10000.0, 300.0
    pl = rng.uniform([50, 50], [1100, 800], (300, 2))
    centre = np.array([575.5, 431.5])
    pb = centre + (pl - centre) * z / (z + 2.0)
    m_lb = Matches(pl, pb, np.eye(2, 3), 0)
    pair = RectifiedPair(np.eye(3), np.eye(3), (1152, 864), (-24, 24), 0.0)
    disparity = np.full((432, 576), f * 2 / z - 20.0, np.float32)
    q, votes = pair_median_offset(m_lb, disparity, pair, f, 2.0, 2.0, PaperSettings(), 4608, rng)
    assert votes > 100
    assert abs(q - 20.0) < 0.01
    depth = depth_from_offset(disparity, pair, q, f, 2.0, (864, 1152))
    assert np.nanmax(np.abs(depth[50:800, 50:1100] - z)) < 0.3
