"""The lens's dense maps against its exact per-point maps."""

from __future__ import annotations

import numpy as np

from rigkit.geometry import Camera, intrinsics
from rigkit.pipeline.lens import GRID_STEP, Lens, smooth_map

# Strong enough to matter: ~110 px at the corner of a 4608x3456 frame.
STRONG = Lens(66000.0, (4608, 3456), (30.0, -200.0, 1e-3, -5e-4, 0.0))


def test_smooth_map_follows_the_exact_map_between_its_knots() -> None:
    rows = (5, 5 + 2 * GRID_STEP + 7)  # off the knot lattice, with a partial last cell
    u, v = smooth_map(STRONG.to_ideal, (0, 4608), rows)
    assert u.shape == v.shape == (rows[1] - rows[0], 4608)
    vv, uu = np.mgrid[rows[0]:rows[1], 0:4608]
    exact = STRONG.to_ideal(np.stack([uu.ravel(), vv.ravel()], 1).astype(np.float64))
    err = np.hypot(u.ravel() - exact[:, 0], v.ravel() - exact[:, 1])
    assert np.abs(exact - np.stack([uu.ravel(), vv.ravel()], 1)).max() > 50
    assert err.max() < 0.005
    knots = (vv.ravel() - rows[0]) % GRID_STEP == 0
    knots &= uu.ravel() % GRID_STEP == 0
    assert err[knots].max() < 1e-9


def test_ideal_rows_without_distortion_are_the_pixel_indices() -> None:
    u, v = Lens(66000.0, (640, 480)).ideal_rows(100, 164)
    assert u.shape == (1, 640) and v.shape == (64, 1)
    assert u[0, 639] == 639 and v[0, 0] == 100 and v[63, 0] == 163


def test_a_principal_point_without_a_bend_is_a_shift_of_every_map() -> None:
    # A view's fitted principal point with no lens bend (issue 35): the maps are the
    # shift, and the dense one stays a row and a column, as without any.
    lens = Lens(66000.0, (640, 480), shift=(3.25, -7.5))
    assert lens.pinhole and not lens.identity
    pts = np.array([[0.0, 0.0], [639.0, 479.0], [100.5, 200.25]])
    assert np.allclose(lens.to_ideal(pts), pts - [3.25, -7.5])
    assert np.allclose(lens.to_recorded(lens.to_ideal(pts)), pts)
    u, v = lens.ideal_rows(100, 164)
    assert u.shape == (1, 640) and v.shape == (64, 1)
    assert u[0, 639] == 639 - 3.25 and v[0, 0] == 100 + 7.5


def test_a_view_bent_about_its_own_centre_maps_to_a_centred_pinhole() -> None:
    # The camera's principal point (its centre of distortion) 20 px right and 12 px up
    # of the image centre: that point is the ideal image's centre, the ideal pixels
    # are the undistorted ones about it, and the two maps invert each other.
    lens = Lens(5000.0, (800, 600), (0.4, 0.0, 0.0, 0.0, 0.0), shift=(20.0, -12.0))
    assert not lens.identity
    assert not Lens(5000.0, (800, 600), shift=(1.0, 0.0)).identity  # a shift alone moves them
    centre = np.array([[399.5 + 20.0, 299.5 - 12.0]])
    assert np.allclose(lens.to_ideal(centre), [[399.5, 299.5]])
    pts = np.array([[10.0, 20.0], [790.0, 580.0], [400.0, 10.0]])
    assert np.allclose(lens.to_recorded(lens.to_ideal(pts)), pts, atol=1e-6)
    plain = Lens(5000.0, (800, 600), (0.4, 0.0, 0.0, 0.0, 0.0))
    bend = lens.to_ideal(pts) - (pts - np.array([20.0, -12.0]))
    assert np.allclose(bend, plain.to_ideal(pts - np.array([20.0, -12.0])) -
                       (pts - np.array([20.0, -12.0])), atol=1e-9)


def test_rays_back_project_as_the_renderer_casts_them() -> None:
    """A bent lens about a principal point off the centre: the export's and the laser
    comparison's back-projection gives the rays the ray caster cast through the pixels
    (rigkit.geometry.Camera, the synthetic scenes' model), not the pinhole's."""
    shift = (4.5, -3.25)
    distortion = (0.47, -2.0, 2e-4, -1e-4, 0.0)
    lens = Lens(14654.3, (1536, 1152), distortion, shift)
    camera = Camera(intrinsics(14654.3, 767.5 + shift[0], 575.5 + shift[1]), np.eye(3),
                    np.zeros(3), 1536, 1152, distortion)
    pts = np.array([[0.0, 0.0], [1535.0, 1151.0], [767.5, 575.5], [100.25, 900.75]])
    rays = lens.rays(pts)
    assert np.allclose(rays, camera.rays(pts[:, 0], pts[:, 1]), rtol=0, atol=1e-12)
    pinhole = (pts - [767.5 + shift[0], 575.5 + shift[1]]) / 14654.3
    assert np.abs(rays[0, :2] - pinhole[0]).max() * 14654.3 > 1.0  # the corner: > 1 px


def test_ray_rows_are_the_rays_whatever_block_they_come_in() -> None:
    """The dense rays follow the exact ones to the interpolation's 0.005 px, and a row's
    rays are the same bits in any block of rows (its knots on whole multiples)."""
    lens = Lens(5000.0, (800, 600), (0.4, 0.0, 0.0, 0.0, 0.0), shift=(20.0, -12.0))
    x, y = lens.ray_rows(37, 120)
    vv, uu = np.mgrid[37:120, 0:800]
    exact = lens.rays(np.stack([uu.ravel(), vv.ravel()], 1).astype(np.float64))
    assert np.abs(x.ravel() - exact[:, 0]).max() * 5000 < 0.005
    assert np.abs(y.ravel() - exact[:, 1]).max() * 5000 < 0.005
    again_x, again_y = lens.ray_rows(50, 70)
    assert np.array_equal(again_x, x[13:33]) and np.array_equal(again_y, y[13:33])
    flat_x, flat_y = Lens(5000.0, (800, 600), shift=(2.0, 1.0)).ray_rows(10, 12)
    assert flat_x.shape == (1, 800) and flat_y.shape == (2, 1)
    assert flat_x[0, 0] == (0 - 2.0 - 399.5) / 5000 and flat_y[1, 0] == (11 - 1.0 - 299.5) / 5000
