"""The views' motion measured from their matches alone, at any depth (pipeline/motion.py):
known cameras, known points, exact projections."""

from __future__ import annotations

import numpy as np
import pytest

from rigkit.errors import PipelineError
from rigkit.geometry import Camera, euler_to_matrix, intrinsics
from rigkit.pipeline.features import Matches
from rigkit.pipeline.motion import back_view_start, rig_motion, view_motion

W, H, F = 1536, 1152, 14650.0
CENTRE = np.array([(W - 1) / 2, (H - 1) / 2])


def _camera(centre: tuple[float, float, float], euler: tuple[float, float, float]) -> Camera:
    K = intrinsics(F, *CENTRE)
    return Camera(K=K, R=euler_to_matrix(*euler).T, C=np.array(centre), width=W, height=H)


def _points(rng: np.random.Generator, n: int, near: float, far: float) -> np.ndarray:
    """(n, 3) points over the left view whose depth recedes from ``near`` at the bottom
    row to ``far`` at the top (a ground seen from above), with some scatter."""
    u, v = rng.uniform(0, W - 1, n), rng.uniform(0, H - 1, n)
    frac = v / (H - 1)  # 0 at the top
    inv = 1 / far + (1 / near - 1 / far) * frac
    z = 1 / inv * (1 + 0.02 * rng.standard_normal(n))
    return np.stack([(u - CENTRE[0]) / F * z, (v - CENTRE[1]) / F * z, z], axis=1)


def _matches(left: Camera, other: Camera, X: np.ndarray, noise_px: float,
             rng: np.random.Generator) -> Matches:
    pl, _ = left.project(X)
    po, _ = other.project(X)
    po = po + noise_px * rng.standard_normal(po.shape)
    return Matches(pl, po, np.array([[1.0, 0, 0], [0, 1.0, 0]]), len(pl))


RIGHT = ((2.0, 0.04, 0.0), (0.4, -0.8, 4.0))  # beside, 4 cm higher
BACK = ((0.1, -0.3, -2.0), (-0.7, 0.9, -4.5))  # raised 0.3 m: stretches an affine map by 1 %


@pytest.mark.parametrize("near, far", [(300.0, 300.0), (200.0, 400.0), (180.0, 450.0)])
def test_the_back_views_magnification_is_recovered_where_depth_recedes(near, far) -> None:
    rng = np.random.default_rng(1)
    left = _camera((0, 0, 0), (0, 0, 0))
    right, back = _camera(*RIGHT), _camera(*BACK)
    X = _points(rng, 1500, near, far)
    m_lr, m_lb = _matches(left, right, X, 0.1, rng), _matches(left, back, X, 0.1, rng)
    tracks = (m_lr.left, m_lr.other, m_lb.other)
    r, b = rig_motion(m_lr, m_lb, F, CENTRE, tracks)
    mean_w = float(np.mean(1 / X[:, 2]))
    assert b.scale == pytest.approx(1 / (1 + 2.0 * mean_w), abs=2e-5)  # 1 - m ~ 7e-3
    assert r.scale == pytest.approx(1.0, abs=1e-4)
    # where it moved: 0.1 m right, 0.3 m up, per metre behind
    assert b.translation[:2] == pytest.approx([0.05, -0.15], abs=0.01)
    # the turn that moves the image as the back camera's pose does at the mean depth:
    # its offset's parallax there (C_y w, -C_x w) goes to the turn, as the fits that
    # start from it with no offset need
    offset = np.array([back.C[1], -back.C[0], 0.0]) * mean_w
    assert b.rotvec == pytest.approx(_rotvec(back.R) + offset, abs=1e-4)  # 1.5 px
    z0, rotvec = back_view_start(b, 2.0)
    assert z0 == pytest.approx(1 / mean_w, rel=0.01)


def test_each_view_alone_gives_its_scale() -> None:
    rng = np.random.default_rng(2)
    left = _camera((0, 0, 0), (0, 0, 0))
    X = _points(rng, 1500, 200.0, 400.0)
    m = _matches(left, _camera(*BACK), X, 0.05, rng)
    b = view_motion(m, F, CENTRE, "z")
    # alone, the back view's scale is its depths' mean weighed by how far each moves
    # the point: |c| = |p - C_xy / C_lb| from its epipole (C_xy / C_lb = (0.05, -0.15))
    reach = np.sum(((m.left - CENTRE) / F + [0.05, -0.15]) ** 2, axis=1)
    mean_w = np.average(1 / X[:, 2], weights=reach)
    assert b.scale == pytest.approx(1 / (1 + 2.0 * mean_w), abs=5e-5)
    zoomed = _camera(RIGHT[0], RIGHT[1])
    zoomed = Camera(K=intrinsics(F * 1.02, *CENTRE), R=zoomed.R, C=zoomed.C, width=W, height=H)
    r = view_motion(_matches(left, zoomed, X, 0.05, rng), F, CENTRE, "x")
    assert r.scale == pytest.approx(1.02, abs=3e-4)


def test_a_view_taken_where_the_left_one_was_shows_no_magnification() -> None:
    rng = np.random.default_rng(3)
    left = _camera((0, 0, 0), (0, 0, 0))
    X = _points(rng, 800, 200.0, 400.0)
    b = view_motion(_matches(left, _camera((0, 0, 0), BACK[1]), X, 0.05, rng), F, CENTRE, "z")
    assert b.scale == pytest.approx(1.0, abs=1e-4)
    with pytest.raises(PipelineError, match="as large as the left|no magnification"):
        back_view_start(b, 2.0)


def test_too_few_matches_is_one_line() -> None:
    m = Matches(np.zeros((5, 2)), np.zeros((5, 2)), np.eye(2, 3), 5)
    with pytest.raises(PipelineError, match="only 5 matches"):
        view_motion(m, F, CENTRE, "z")


def _rotvec(R: np.ndarray) -> np.ndarray:
    angle = np.arccos(np.clip((np.trace(R) - 1) / 2, -1, 1))
    axis = np.array([R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1]])
    return axis / np.linalg.norm(axis) * angle
