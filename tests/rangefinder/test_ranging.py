"""The one range <-> z conversion, against a ray-traced synthetic scene's ground truth."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from rigkit.geometry import NO_DISTORTION
from rigkit.pipeline.lens import Lens
from rigkit.rangefinder.ranging import (
    aperture_offset,
    depth_from_range,
    depth_on_ray,
    range_from_depth,
    range_on_ray,
)
from rigkit.rig import rig_from_data
from rigkit.synth import SceneTruth

OFFSET = (0.35, 0.12, -0.40)  # aperture right, up, forward of the left camera, metres


def _profile(truth: SceneTruth, principal_point: list[float] | None) -> object:
    """A rig profile of the scene's left camera; ``principal_point`` as a profile states
    it (from the top-left pixel's corner) or None."""
    left = truth.cameras["left"]
    camera: dict = {
        "model": "synthetic pinhole",
        "resolution": [left.width, left.height],
        "focal_length": {"px": left.f, "tolerance_fraction": 0.0},
    }
    if principal_point is not None:
        camera["principal_point_px"] = principal_point
    data = {
        "version": 1,
        "name": "ranging-test",
        "camera": camera,
        "baselines": {"C_lr": {"value_m": 2.0, "tolerance_m": 0.0},
                      "C_lb": {"value_m": 2.0, "tolerance_m": 0.0}},
        "rangefinder": {"protocol": "manual", "offset": dict(
            zip(("right_m", "up_m", "forward_m"), OFFSET, strict=True))},
    }
    return rig_from_data(data, Path("ranging-test.yaml"))


def _pixels_and_truth(truth: SceneTruth) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Pixels spread over the image (corners included) with a surface, their ground-truth
    depth, and the true range from the aperture to the ray-traced 3D point."""
    left = truth.cameras["left"]
    depth = truth.depth("left").astype(np.float64)
    us = np.linspace(0, left.width - 1, 9).round()
    vs = np.linspace(0, left.height - 1, 7).round()
    u, v = (a.ravel() for a in np.meshgrid(us, vs))
    z = depth[v.astype(int), u.astype(int)]
    keep = np.isfinite(z)
    u, v, z = u[keep], v[keep], z[keep]
    points = left.rays(u, v) * z[:, None] + left.C  # world = left camera frame (y down)
    aperture = np.array([OFFSET[0], -OFFSET[1], OFFSET[2]])  # up is -y in camera axes
    return np.stack([u, v], 1), z, np.linalg.norm(points - aperture, axis=1)


def test_profile_principal_point_is_moved_to_pixel_centres(truth: SceneTruth) -> None:
    left = truth.cameras["left"]
    cx, cy = left.K[0, 2], left.K[1, 2]
    profile = _profile(truth, [cx + 0.5, cy + 0.5])  # corner convention
    camera = profile.intrinsics((left.width, left.height))
    assert (camera.focal_px, camera.cx_px, camera.cy_px) == pytest.approx((left.f, cx, cy),
                                                                          abs=1e-9)
    # The pipeline gets the same point, as its offset from the image centre.
    centre = ((left.width - 1) / 2, (left.height - 1) / 2)
    assert profile.geometry().principal_points_px[0] == pytest.approx(
        (cx - centre[0], cy - centre[1]), abs=1e-9)
    centred = _profile(truth, None).intrinsics((left.width, left.height))
    assert (centred.cx_px, centred.cy_px) == centre and centred.centre_offset_px == (0, 0)
    assert aperture_offset(profile) == OFFSET


def test_range_and_depth_recover_ray_traced_truth(truth: SceneTruth) -> None:
    left = truth.cameras["left"]
    pixels, z_true, r_true = _pixels_and_truth(truth)
    assert len(pixels) > 40
    profile = _profile(truth, [left.K[0, 2] + 0.5, left.K[1, 2] + 0.5])
    camera = profile.intrinsics((left.width, left.height))
    f, cx, cy = camera.focal_px, camera.cx_px, camera.cy_px
    lens = Lens(f, (left.width, left.height), NO_DISTORTION,
                profile.geometry().principal_points_px[0])
    for (u, v), z, r in zip(pixels, z_true, r_true, strict=True):
        intrinsics = {"fx": f, "fy": f, "cx": cx, "cy": cy, "offset_m": OFFSET}
        r_est = range_from_depth(z, (u, v), **intrinsics)
        z_est = depth_from_range(r, (u, v), **intrinsics)
        assert r_est == pytest.approx(r, rel=1e-6)
        assert z_est == pytest.approx(z, rel=1e-6)
        # Each recovers the other (to rounding, far tighter than the truth check).
        assert depth_from_range(r_est, (u, v), **intrinsics) == pytest.approx(z, rel=1e-12)
        assert range_from_depth(z_est, (u, v), **intrinsics) == pytest.approx(r, rel=1e-12)
        # The lens's ray (the laser comparison's and export's) is the pinhole's here.
        ray = tuple(lens.rays(np.array([[u, v]]))[0])
        assert range_on_ray(z, ray, OFFSET) == pytest.approx(r_est, rel=1e-12)
        assert depth_on_ray(r, ray, OFFSET) == pytest.approx(z_est, rel=1e-12)


def test_the_corner_convention_would_be_off_at_the_image_edge(truth: SceneTruth) -> None:
    """Taking the profile's corner-based principal point as a centre-based one moves the
    ray by half a pixel; at the image corners that is visible at this tolerance."""
    left = truth.cameras["left"]
    pixels, z_true, r_true = _pixels_and_truth(truth)
    wrong = {"fx": left.f, "fy": left.f, "cx": left.K[0, 2] + 0.5, "cy": left.K[1, 2] + 0.5,
             "offset_m": OFFSET}
    errors = [abs(range_from_depth(z, (u, v), **wrong) / r - 1)
              for (u, v), z, r in zip(pixels, z_true, r_true, strict=True)]
    assert max(errors) > 1e-6
