"""The SfM+MVS baseline: the dense step is exact with true poses; COLMAP registers the
three views of a small scene, scaled to the true baseline."""

from __future__ import annotations

import numpy as np
import pytest

from rigkit.experiments.common import apply_h
from rigkit.experiments.sfm import RigPoses, calibrated_rectification, depth_from_poses
from rigkit.pipeline.features import match_views
from rigkit.synth.evaluate import depth_metrics, visible_in_right

VIEWS = ("left", "right", "back")


@pytest.fixture(scope="module")
def matches(images):
    return (
        match_views(images["left"], images["right"]),
        match_views(images["left"], images["back"]),
    )


def test_calibrated_rectification_aligns_rows(truth):
    left, right = truth.cameras["left"], truth.cameras["right"]
    _, H_l, H_r = calibrated_rectification(left.K, right.K, right.R, right.C)
    X = np.random.default_rng(0).uniform([-10, -8, 280], [10, 8, 320], (200, 3))
    rows_l = apply_h(H_l, left.project(X)[0])[:, 1]
    rows_r = apply_h(H_r, right.project(X)[0])[:, 1]
    assert np.max(np.abs(rows_l - rows_r)) < 1e-6


def test_dense_step_with_true_poses_is_accurate(truth, images, matches):
    K = {v: truth.cameras[v].K for v in VIEWS}
    poses = RigPoses({v: truth.cameras[v].R for v in VIEWS}, {v: truth.cameras[v].C for v in VIEWS})
    depth = depth_from_poses(images["left"], images["right"], K, poses, matches[0])
    m = depth_metrics(depth, truth.depth("left"), visible_in_right(truth))
    assert m.under_1 > 0.9 and abs(m.median_bias) < 0.003


def test_colmap_registers_the_views_at_the_true_baseline(truth, images, matches):
    pytest.importorskip("pycolmap")
    from rigkit.experiments.sfm import colmap_poses

    K = {v: truth.cameras[v].K for v in VIEWS}
    poses = colmap_poses(images, K, *matches, 2.0, np.random.default_rng(0))
    assert np.allclose(poses.R["left"], np.eye(3)) and np.allclose(poses.C["left"], 0)
    assert np.linalg.norm(poses.C["right"]) == pytest.approx(2.0)
    # Near the truth, but not exact: the rotation error about y is the bas-relief.
    assert poses.C["right"][0] > 1.9
    angle = np.arccos((np.trace(poses.R["right"] @ truth.cameras["right"].R.T) - 1) / 2)
    assert np.degrees(angle) < 1.0
