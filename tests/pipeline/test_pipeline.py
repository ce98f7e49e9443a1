"""Each pipeline stage against ground truth, end to end, and bad inputs."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from rigkit.errors import InputError, PipelineError
from rigkit.evaluate import depth_metrics, visible_in_right
from rigkit.pipeline import RigGeometry, estimate_depth
from rigkit.pipeline.depth import triangulate_z
from rigkit.pipeline.features import match_views
from rigkit.pipeline.rectify import apply_homography


def _true_correspondences(truth, view: str, n: int = 4000, seed: int = 0):
    """Left pixels and where ``view`` truly sees the same points (visible ones only)."""
    rng = np.random.default_rng(seed)
    left, cam = truth.cameras["left"], truth.cameras[view]
    u = rng.uniform(10, left.width - 11, n)
    v = rng.uniform(10, left.height - 11, n)
    zl = truth.depth("left")
    z = zl[np.rint(v).astype(int), np.rint(u).astype(int)].astype(np.float64)
    X = left.rays(u, v) * z[:, None] + left.C
    uv, zc = cam.project(X)
    ui, vi = np.rint(uv[:, 0]).astype(int), np.rint(uv[:, 1]).astype(int)
    ok = (ui >= 0) & (ui < cam.width) & (vi >= 0) & (vi < cam.height)
    zv = np.full(n, np.nan)
    zv[ok] = truth.depth(view)[vi[ok], ui[ok]]
    # Same surface in both views, and away from depth edges in the left view.
    ok &= np.abs(zv - zc) < 1e-3 * zc
    edge = cv2.dilate(zl, np.ones((9, 9))) - cv2.erode(zl, np.ones((9, 9)))
    ok &= edge[np.rint(v).astype(int), np.rint(u).astype(int)] < 0.3
    return np.stack([u, v], 1)[ok], uv[ok], z[ok]


def _ideal(result, view: int, pts: np.ndarray) -> np.ndarray:
    """Recorded pixels (N, 2) of view ``view`` (0 left, 1 right, 2 back) as the pipeline's
    later stages see them: through the lens fitted from the views, which takes each
    view's principal point out (rigkit.pipeline.lens)."""
    h, w = result.depth.shape
    lens = result.lens_fit.lens(result.rectification.K[0, 0], (w, h), view)
    return lens.to_ideal(pts)


def test_matches_are_subpixel_accurate(truth, images) -> None:
    m = match_views(images["left"], images["back"], "left/back")
    left, back = truth.cameras["left"], truth.cameras["back"]
    z = cv2.remap(
        truth.depth("left"),
        m.left[:, 0].astype(np.float32).reshape(-1, 1),
        m.left[:, 1].astype(np.float32).reshape(-1, 1),
        cv2.INTER_LINEAR,
    ).ravel()
    uv, _ = back.project(left.rays(m.left[:, 0], m.left[:, 1]) * z[:, None] + left.C)
    err = np.linalg.norm(uv - m.other, axis=1)
    assert len(err) > 500 and np.median(err) < 0.15


def test_rectification_puts_true_correspondences_on_one_row(truth, result) -> None:
    pl, pr, _ = _true_correspondences(truth, "right")
    pl, pr = _ideal(result, 0, pl), _ideal(result, 1, pr)
    r = result.rectification
    rows = apply_homography(r.H_left, pl)[:, 1] - apply_homography(r.H_right, pr)[:, 1]
    assert len(rows) > 1000
    assert np.percentile(np.abs(rows), 95) < 0.15
    # Rotations, not affine approximations: the fitted right-camera roll matches truth.
    R_true = truth.cameras["right"].R.T  # right camera -> left frame
    roll_err = np.degrees(cv2.Rodrigues(r.R_lr.T @ R_true)[0].ravel()[2])
    assert abs(roll_err) < 0.01


def test_stereo_disparity_matches_true_rectified_disparity(truth, result) -> None:
    pl, pr, _ = _true_correspondences(truth, "right")
    pl, pr = _ideal(result, 0, pl), _ideal(result, 1, pr)
    r = result.rectification
    xl, xr = apply_homography(r.H_left, pl), apply_homography(r.H_right, pr)
    s = result.disparity_scale
    xs = (xl * s + 0.5 * s - 0.5).astype(np.float32).reshape(-1, 1, 2)
    est = cv2.remap(result.disparity, xs[..., 0], xs[..., 1], cv2.INTER_LINEAR).ravel() / s
    err = np.abs(est - (xl[:, 0] - xr[:, 0]))
    err = err[np.isfinite(err)]
    assert len(err) > 0.9 * len(xl)
    assert np.median(err) < 0.25 and np.percentile(err, 90) < 0.6


def test_ambiguity_removal_recovers_metric_scale(truth, result, rig) -> None:
    """With the true rectified disparity, the fitted offset gives the true depth."""
    pl, pr, z = _true_correspondences(truth, "right")
    pl, pr = _ideal(result, 0, pl), _ideal(result, 1, pr)
    r = result.rectification
    xl, xr = apply_homography(r.H_left, pl), apply_homography(r.H_right, pr)
    zt = triangulate_z(r, xl[:, 0], xl[:, 0] - xr[:, 0], result.ambiguity.beta, rig.baseline_lr_m)
    rel = (zt - z) / z
    # At 960 px the back view's magnification signal is small: the offset is good to
    # ~0.5 px (~1 %); at full resolution to ~0.1-0.5 px of ~293 (benchmarks/).
    assert abs(np.median(rel)) < 0.012
    # Its sigma is the size of its error (~0.5 px here): not exploding.
    assert result.ambiguity.offset_sigma_px < 0.6
    # The back camera's raise (0.3 m) is recovered although nobody told the pipeline.
    assert result.ambiguity.back_offset_m[1] == pytest.approx(-0.3, abs=0.08)


def test_end_to_end_depth_accuracy(truth, result) -> None:
    gt = truth.depth("left")
    assert result.depth.shape == gt.shape and result.depth.dtype == np.float32
    m = depth_metrics(result.depth, gt, visible_in_right(truth))
    # Small-image bar (see test_ambiguity_removal_recovers_metric_scale); the paper's
    # full-resolution protocol is scored by benchmarks/eval_synthetic.py.
    assert m.under_3 > 0.97 and m.under_1 > 0.6
    assert m.density > 0.97 and abs(m.median_bias) < 0.012
    assert np.all(result.sigma[np.isfinite(result.depth)] > 0)


# ---- bad inputs -------------------------------------------------------------------


def test_images_of_different_sizes(images, rig) -> None:
    with pytest.raises(InputError, match="differ in size"):
        estimate_depth(images["left"], images["right"][:-2], images["back"], rig)


def test_non_positive_rig_values() -> None:
    with pytest.raises(InputError, match="focal_px"):
        RigGeometry(-1.0, 2.0, 2.0)
    with pytest.raises(InputError, match="baseline_lb_m"):
        RigGeometry(40000.0, 2.0, 0.0)


def test_textureless_images(rig) -> None:
    flat = np.full((480, 640), 128, np.float32)
    with pytest.raises(PipelineError, match="left/right: only 0 features"):
        estimate_depth(flat, flat, flat, rig)


def test_unrelated_images(images, rig) -> None:
    noise = np.random.default_rng(1).uniform(0, 255, images["left"].shape).astype(np.float32)
    noise = cv2.GaussianBlur(noise, (0, 0), 1.0)
    with pytest.raises(PipelineError, match="same scene"):
        estimate_depth(images["left"], noise, images["back"], rig)


def test_back_image_not_behind_the_left(images, rig) -> None:
    # A view that magnifies the scene relative to the left was taken in front of it.
    h, w = images["left"].shape
    zoom = cv2.warpAffine(
        images["left"], cv2.getRotationMatrix2D((w / 2, h / 2), 0.0, 1.01), (w, h)
    )
    with pytest.raises(PipelineError, match="behind the left camera"):
        estimate_depth(images["left"], images["right"], zoom, rig)


def test_left_and_right_swapped(images, rig) -> None:
    with pytest.raises(PipelineError, match="swapped"):
        estimate_depth(images["right"], images["left"], images["back"], rig)
