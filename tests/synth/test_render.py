"""The renderer against its own geometry."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from rigkit.errors import InputError
from rigkit.synth import SynthParams, generate_scene
from rigkit.synth.render import _terrain_t, render_view


def _sample(img: np.ndarray, uv: np.ndarray) -> np.ndarray:
    m = uv.astype(np.float32).reshape(-1, 1, 2)
    return cv2.remap(img, m[..., 0], m[..., 1], cv2.INTER_LINEAR).ravel()


def test_points_project_where_the_other_views_see_them(truth) -> None:
    """Left pixels lifted to 3D with the left depth land in the right and back depth
    maps at the depth the projection predicts (for points those views see)."""
    rng = np.random.default_rng(0)
    left = truth.cameras["left"]
    u = rng.uniform(20, left.width - 21, 3000)
    v = rng.uniform(20, left.height - 21, 3000)
    z = _sample(truth.depth("left"), np.stack([u, v], 1))
    X = left.rays(u, v) * z[:, None] + left.C
    for view in ("right", "back"):
        cam = truth.cameras[view]
        uv, zc = cam.project(X)
        inside = (uv[:, 0] > 1) & (uv[:, 0] < cam.width - 2) & (uv[:, 1] > 1)
        inside &= uv[:, 1] < cam.height - 2
        zr = _sample(truth.depth(view), uv[inside])
        rel = np.abs(zr - zc[inside]) / zc[inside]
        # Most points are seen (not occluded) and agree to interpolation accuracy.
        assert np.mean(rel < 1e-4) > 0.9, view


def test_images_show_the_same_surface_where_geometry_says(truth, images) -> None:
    """A textured left patch reappears in the right image at the projected position."""
    left, right = truth.cameras["left"], truth.cameras["right"]
    zl = truth.depth("left")
    scores = []
    for v, u in [(200, 300), (400, 500), (500, 700), (300, 650)]:
        X = left.rays(np.array([u], float), np.array([v], float)) * zl[v, u] + left.C
        (ur, vr), _ = right.project(X)[0][0], None
        if not (15 < ur < right.width - 16 and 15 < vr < right.height - 16):
            continue
        a = images["left"][v - 7 : v + 8, u - 7 : u + 8]
        b = cv2.getRectSubPix(images["right"], (15, 15), (float(ur), float(vr)))
        scores.append(np.corrcoef(a.ravel(), b.ravel())[0, 1])
    assert scores and np.median(scores) > 0.6


def test_terrain_intersection_is_exact(truth) -> None:
    scene = generate_scene(SynthParams(width=200, height=150), seed=5)
    cam = scene.cameras["back"]
    u, v = np.meshgrid(np.linspace(0, 199, 17), np.linspace(0, 149, 13))
    d = cam.rays(u, v)
    t = _terrain_t(scene, cam.C, d, np.full(u.shape, 300.0), iters=30)
    p = cam.C + t[..., None] * d
    assert np.max(np.abs(p[..., 2] - scene.terrain.z(p[..., 0], p[..., 1]))) < 1e-6


def test_same_seed_same_scene_and_depth_is_camera_z() -> None:
    p = SynthParams(width=160, height=120)
    a, b = generate_scene(p, 11), generate_scene(p, 11)
    ra, da = render_view(a, "left")
    rb, db = render_view(b, "left")
    assert np.array_equal(ra, rb) and np.array_equal(da, db, equal_nan=True)
    assert not np.array_equal(render_view(generate_scene(p, 12), "left")[1], da)
    # Scene sits at the requested distance, with a few percent of relief.
    assert 0.9 * p.distance_m < np.nanmedian(da) < 1.1 * p.distance_m


def test_protocol_rotations_and_principal_points_are_within_bounds(truth) -> None:
    scene = generate_scene(SynthParams(width=400, height=300), seed=9)
    for name in ("right", "back"):
        x, y, z = scene.euler_deg[name]
        assert abs(x) <= 1 and abs(y) <= 1 and abs(z) <= 5
        K = scene.cameras[name].K
        assert abs(K[0, 2] - 199.5) <= 30 and abs(K[1, 2] - 149.5) <= 30
    assert np.allclose(scene.cameras["right"].C, [2, 0, 0])
    assert np.allclose(scene.cameras["back"].C, [0, -0.3, -2])


def test_one_camera_shares_its_principal_point_and_draws_the_same_poses() -> None:
    three = generate_scene(SynthParams(width=400, height=300), seed=9)
    one = generate_scene(SynthParams(width=400, height=300, one_camera=True), seed=9)
    left = one.cameras["left"].K[:2, 2]
    assert np.array_equal(left, three.cameras["left"].K[:2, 2])
    assert not np.allclose(left, [199.5, 149.5])  # off centre, as a real camera's
    for name in ("right", "back"):
        assert np.array_equal(one.cameras[name].K[:2, 2], left)
        assert one.euler_deg[name] == three.euler_deg[name]  # only the intrinsics differ


def test_bad_parameters_are_rejected() -> None:
    with pytest.raises(InputError, match="hfov_deg"):
        generate_scene(SynthParams(hfov_deg=0.0), 1)
