"""The bas-relief simulation: exact without noise; with noise the error goes into the
rotation about y, as the paper's sec. 5.1 shows."""

from __future__ import annotations

import numpy as np

from rigkit.experiments.basrelief import (
    BasReliefSetup,
    euler_xyz_deg,
    run_many,
    run_once,
    surface_points,
)
from rigkit.geometry import euler_to_matrix


def test_points_lie_on_the_surface_and_in_both_views():
    s = BasReliefSetup()
    X = surface_points(s, np.random.default_rng(0))
    assert X.shape == (1500, 3)
    z = s.a + s.b * np.exp(-(X[:, 0] ** 2 + X[:, 1] ** 2) / (2 * s.sigma**2))
    assert np.allclose(X[:, 2], z)
    f = s.K[0, 0]
    for cx in (0.0, s.baseline_m):
        u = (X[:, 0] - cx) / X[:, 2] * f + s.K[0, 2]
        assert u.min() >= 0 and u.max() <= s.width - 1


def test_without_noise_two_view_sfm_recovers_the_true_geometry():
    run = run_once(BasReliefSetup(noise_sigma_px=0.0), np.random.default_rng(1))
    assert np.max(np.abs(run.euler_error_deg)) < 1e-6
    assert run.t_error_deg < 1e-4
    assert np.max(np.abs(run.depth_error)) < 1e-6


def test_with_noise_the_error_is_a_rotation_about_y():
    _, summary = run_many(BasReliefSetup(), 8, np.random.default_rng(2))
    x, y, z = summary.rot_median_deg
    assert y > 0.05 and y > 20 * x and y > 5 * z


def test_euler_angles_round_trip():
    R = euler_to_matrix(0.3, -0.2, 4.0)
    assert np.allclose(euler_xyz_deg(R), [0.3, -0.2, 4.0])
