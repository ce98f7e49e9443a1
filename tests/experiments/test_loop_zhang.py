"""Loop-Zhang rectification and the 8-point fundamental matrix, against a pair of
cameras whose F is known exactly."""

from __future__ import annotations

import numpy as np
import pytest

from rigkit.experiments.common import apply_h
from rigkit.experiments.loop_zhang import (
    eight_point,
    fundamental_ransac,
    rectifying_homographies,
    sampson,
)
from rigkit.geometry import euler_to_matrix, intrinsics

SIZE = (1152, 864)


def _pair(rng, euler=(0.5, -0.7, 3.0), centre=(2.0, 0.0, 0.0), n=400):
    """Matches of points ~300 m away seen by a left camera at the origin and a rotated
    right camera; and the exact F (x_r^T F x_l = 0)."""
    Kl = intrinsics(10990.0, 585.0, 424.0)
    Kr = intrinsics(10990.0, 570.0, 445.0)
    R = euler_to_matrix(*euler).T  # world -> right camera
    C = np.array(centre)
    X = rng.uniform([-15, -11, 280], [15, 11, 330], (n, 3))

    def project(K, R, C):
        Xc = (X - C) @ R.T
        return Xc[:, :2] / Xc[:, 2:] * K[0, 0] + K[:2, 2]

    t = -R @ C
    tx = np.array([[0, -t[2], t[1]], [t[2], 0, -t[0]], [-t[1], t[0], 0]])
    F = np.linalg.inv(Kr).T @ tx @ R @ np.linalg.inv(Kl)
    return project(Kl, np.eye(3), np.zeros(3)), project(Kr, R, C), F


@pytest.mark.parametrize("euler", [(0.5, -0.7, 3.0), (-1.0, 1.0, -5.0), (0.0, 0.0, 0.0)])
def test_homographies_put_matches_on_one_row(euler):
    pl, pr, F = _pair(np.random.default_rng(1), euler)
    H_l, H_r = rectifying_homographies(F, SIZE)
    rows_l, rows_r = apply_h(H_l, pl)[:, 1], apply_h(H_r, pr)[:, 1]
    assert np.max(np.abs(rows_l - rows_r)) < 1e-6
    # The rectified F is the one of a horizontal baseline: [1, 0, 0]_x up to scale.
    Fr = np.linalg.inv(H_r).T @ F @ np.linalg.inv(H_l)
    Fr /= Fr[2, 1]
    assert np.allclose(Fr, [[0, 0, 0], [0, 0, -1], [0, 1, 0]], atol=1e-6)


def test_shear_keeps_mid_lines_perpendicular_and_in_aspect():
    _, _, F = _pair(np.random.default_rng(2))
    w, h = SIZE
    H_l, _ = rectifying_homographies(F, SIZE)
    mid = np.array([[(w - 1) / 2, 0], [w - 1, (h - 1) / 2], [(w - 1) / 2, h - 1], [0, (h - 1) / 2]])
    a, b, c, d = apply_h(H_l, mid)
    x, y = b - d, c - a
    assert abs(x @ y) / (np.linalg.norm(x) * np.linalg.norm(y)) < 1e-9
    assert np.linalg.norm(x) / np.linalg.norm(y) == pytest.approx(w / h, rel=1e-9)
    assert x[0] > 0 and y[1] > 0  # neither mirrored nor upside down


def test_eight_point_recovers_f_and_ransac_rejects_outliers():
    rng = np.random.default_rng(3)
    pl, pr, F = _pair(rng)
    F8 = eight_point(pl, pr)
    assert np.max(sampson(F8, pl, pr)) < 1e-6
    assert abs(abs(np.sum(F8 * F / np.linalg.norm(F))) - 1) < 1e-6
    bad = rng.choice(len(pr), 60, replace=False)
    pr_out = pr.copy()
    pr_out[bad] += rng.uniform(20, 40, (60, 2))
    _, inliers = fundamental_ransac(pl, pr_out, rng, trials=200)
    assert not inliers[bad].any() and inliers.sum() == len(pl) - 60
