"""Field conditions in the generator: what a real capture adds, checked against the
generator's own exact geometry."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from rigkit.geometry import Camera, distort, intrinsics, undistort
from rigkit.synth import SynthParams, field_params, generate_scene, load_scene, write_scene
from rigkit.synth.evaluate import depth_metrics
from rigkit.synth.render import render_view
from rigkit.synth.shimmer import shimmer_field

TINY = SynthParams(width=320, height=240, n_boxes=2, n_spheres=1)


def test_distortion_model_round_trip() -> None:
    rng = np.random.default_rng(0)
    x, y = rng.uniform(-0.06, 0.06, (2, 500))
    d = (0.5, -3.0, 1e-3, -2e-3, 20.0)
    xd, yd = distort(x, y, d)
    assert np.abs(xd - x).max() > 1e-5  # it does distort
    xu, yu = undistort(xd, yd, d)
    assert np.abs(xu - x).max() < 1e-12 and np.abs(yu - y).max() < 1e-12


def test_distorted_camera_projects_its_own_rays() -> None:
    cam = Camera(intrinsics(5000.0, 160.0, 120.0), np.eye(3), np.zeros(3), 320, 240,
                 distortion=(2.0, 0.0, 0.0, 0.0, 0.0))
    u, v = np.meshgrid(np.arange(0, 320, 40.0), np.arange(0, 240, 40.0))
    uv, z = cam.project(cam.rays(u, v) * 300.0)
    assert np.allclose(z, 300.0)
    assert np.abs(uv[..., 0] - u).max() < 1e-6 and np.abs(uv[..., 1] - v).max() < 1e-6
    # and a corner pixel's ray differs from the pinhole's: the lens bends it
    pinhole = replace(cam, distortion=(0.0,) * 5)
    assert np.abs(cam.rays(np.array(0.0), np.array(0.0)) - pinhole.rays(np.array(0.0),
                  np.array(0.0))).max() > 1e-6


def test_sky_has_no_ground_truth_and_is_smooth() -> None:
    scene = generate_scene(replace(TINY, sky=0.3), seed=4)
    radiance, depth = render_view(scene, "left")
    sky = np.isnan(depth)
    top = sky[: int(0.2 * 240)]
    assert top.mean() > 0.8  # the top of the frame is sky
    assert 0.1 < sky.mean() < 0.5
    rows = radiance[: int(0.2 * 240)][top]
    assert np.abs(np.diff(radiance[:20], axis=1)).max() < 0.01  # no texture in the sky
    assert rows.min() > 0.5


def test_no_sky_by_default() -> None:
    _, depth = render_view(generate_scene(TINY, seed=4), "left")
    assert np.isfinite(depth).all()


def test_shimmer_field_has_the_requested_rms_and_correlation() -> None:
    dx, dy = shimmer_field((400, 600), 0.3, 10.0, np.random.default_rng(1))
    for f in (dx, dy):
        assert f.shape == (400, 600)
        assert 0.27 < float(np.sqrt(np.mean(f**2))) < 0.33
        # neighbours move together, points far apart do not
        near = np.corrcoef(f[:, :-2].ravel(), f[:, 2:].ravel())[0, 1]
        far = np.corrcoef(f[:, :-80].ravel(), f[:, 80:].ravel())[0, 1]
        assert near > 0.9 and abs(far) < 0.2


def test_field_preset_and_burst_frames_differ(tmp_path) -> None:
    params = replace(field_params(TINY), burst=3)
    assert params.shimmer_px == 0.3 and params.sky > 0 and params.haze_m > 0
    write_scene(generate_scene(params, seed=2), tmp_path / "s")
    truth = load_scene(tmp_path / "s")
    frames = truth.frame_paths("left")
    assert [p.name for p in frames] == ["left.png", "left-2.png", "left-3.png"]
    import cv2

    a, b = (cv2.imread(str(p), cv2.IMREAD_GRAYSCALE).astype(float) for p in frames[:2])
    assert 0 < np.abs(a - b).mean() < 20  # same view, new shimmer and noise


def test_distortion_is_recorded_with_the_cameras(tmp_path) -> None:
    params = replace(TINY, distortion=(0.4, 0.0, 0.0, 0.0, 0.0))
    write_scene(generate_scene(params, seed=2), tmp_path / "s")
    assert load_scene(tmp_path / "s").cameras["back"].distortion == (0.4, 0.0, 0.0, 0.0, 0.0)


def test_false_depth_counts_estimates_where_there_is_no_surface() -> None:
    truth = np.full((10, 10), 300.0, np.float32)
    truth[:4] = np.nan  # 40 pixels of sky
    est = np.full((10, 10), 300.0, np.float32)
    est[:2] = np.nan  # 20 of them left empty, 20 given a depth
    m = depth_metrics(est, truth, np.isfinite(truth))
    assert m.false_depth == pytest.approx(0.5)
    assert m.under_1 == 1.0
    assert np.isnan(depth_metrics(est, np.full((10, 10), 300.0), np.ones((10, 10), bool))
                    .false_depth)
