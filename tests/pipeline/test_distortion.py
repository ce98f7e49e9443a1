"""The lens fitted from the three views, on exact projections with known cameras: it
recovers the bend, and keeps the given lens when the views cannot tell it from noise
or see too few corners in common."""

from __future__ import annotations

from dataclasses import replace

import cv2
import numpy as np
import pytest
from scipy.optimize import least_squares

from rigkit.geometry import Camera, euler_to_matrix, focal_from_fov, intrinsics
from rigkit.pipeline.ambiguity import spatial_blocks
from rigkit.pipeline.bundle import Problem, corner_radius, initial
from rigkit.pipeline.covariance import cluster_covariance
from rigkit.pipeline.distortion import (
    corner_shift_px,
    fit_distortion,
    refine_lens,
    three_view_tracks,
)
from rigkit.pipeline.features import Matches
from rigkit.pipeline.lens import Lens
from rigkit.pipeline.motion import back_view_start, rig_motion
from rigkit.pipeline.rectify import pseudo_rectify
from rigkit.pipeline.rig import RigGeometry
from rigkit.pipeline.settings import PipelineSettings
from rigkit.synth.shimmer import shimmer_field

W, H = 1600, 1200
F = focal_from_fov(W, 5.0)


def _affine(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return np.linalg.lstsq(np.c_[a, np.ones(len(a))], b, rcond=None)[0].T


def _tracks(k1: float, noise_px: float, rng: np.random.Generator, n: int = 1200,
            pp: dict[str, tuple[float, float]] | None = None):
    """Left/right and left/back matches of points 250-350 m away, seen by one lens at
    the three positions (right 2 m to the side, back 2 m behind and 0.3 m up, each
    turned by about a degree); Gaussian noise of ``noise_px`` on the other views;
    ``pp``: a view's principal point offset from the image centre (px)."""
    pp = pp or {}

    def K(name: str) -> np.ndarray:
        dx, dy = pp.get(name, (0.0, 0.0))
        return intrinsics(F, (W - 1) / 2 + dx, (H - 1) / 2 + dy)

    lens = (k1, 0.0, 0.0, 0.0, 0.0)
    cams = {
        name: Camera(K=K(name), R=euler_to_matrix(*e).T, C=np.array(c), width=W, height=H,
                     distortion=lens)
        for name, e, c in (
            ("left", (0, 0, 0), (0.0, 0.0, 0.0)),
            ("right", (0.6, -0.8, 2.0), (2.0, 0.0, 0.0)),
            ("back", (-0.5, 0.7, -3.0), (0.0, -0.3, -2.0)),
        )
    }
    u, v = rng.uniform(20, W - 20, n), rng.uniform(20, H - 20, n)
    X = cams["left"].rays(u, v) * rng.uniform(250, 350, n)[:, None]
    left = np.stack([u, v], axis=1)
    seen = {}
    for name in ("right", "back"):
        p, _ = cams[name].project(X)
        seen[name] = p + rng.normal(0, noise_px, p.shape)
    inside = np.all([(p[:, 0] > 0) & (p[:, 0] < W) & (p[:, 1] > 0) & (p[:, 1] < H)
                     for p in seen.values()], axis=0)
    left = left[inside]
    return tuple(
        Matches(left, seen[name][inside], _affine(left, seen[name][inside]), int(inside.sum()))
        for name in ("right", "back")
    )


RIG = RigGeometry(F, 2.0, 2.0)


def _settings(pp_sigma_px: float) -> PipelineSettings:
    """The pipeline's defaults, each view's principal point held by a prior of
    ``pp_sigma_px`` (0: at the image centre)."""
    return PipelineSettings(principal_point_sigma=pp_sigma_px / W)


def _fit(m_lr: Matches, m_lb: Matches, start=(0.0,) * 5, pp_sigma_px: float = 0.0):
    lens = Lens(F, (W, H), start)
    rect = pseudo_rectify(m_lr, F, (W, H))
    return fit_distortion(m_lr, m_lb, rect, lens, RIG, _settings(pp_sigma_px))


def _k1_for_corner(fraction: float) -> float:
    return fraction / (np.hypot(W - 1, H - 1) / 2 / F) ** 2


def test_recovers_the_bend_from_exact_projections() -> None:
    k1 = _k1_for_corner(0.003)  # 0.3 % at the corner: ~3 px
    fit = _fit(*_tracks(k1, 0.0, np.random.default_rng(1)))
    true = corner_shift_px(Lens(F, (W, H), (k1, 0, 0, 0, 0)))
    assert true == pytest.approx(0.003 * np.hypot(W - 1, H - 1) / 2, rel=0.01)
    assert fit.significant and fit.distortion == fit.fitted
    assert fit.corner_px == pytest.approx(true, abs=1e-3)
    assert fit.rms_px < 1e-3


def test_a_wrong_start_is_corrected() -> None:
    k1 = _k1_for_corner(0.003)
    fit = _fit(*_tracks(k1, 0.05, np.random.default_rng(2)), start=(3 * k1, 0, 0, 0, 0))
    true = corner_shift_px(Lens(F, (W, H), (k1, 0, 0, 0, 0)))
    assert fit.start_corner_px == pytest.approx(3 * true, rel=0.01)
    assert fit.significant
    assert abs(fit.corner_px - true) < max(4 * fit.corner_sigma_px, 0.05 * true)


def test_noise_alone_does_not_change_the_lens() -> None:
    # No distortion, 0.3 px of noise (shimmer-sized): the fit wanders by about its
    # sigma, and the pipeline keeps the given (here: no) distortion.
    fit = _fit(*_tracks(0.0, 0.3, np.random.default_rng(3)))
    assert abs(fit.corner_px) < 3 * fit.corner_sigma_px
    assert not fit.significant and fit.distortion == (0.0,) * 5
    assert fit.offset_sigma_px >= 0.0


def test_too_few_three_view_tracks_keep_the_given_lens() -> None:
    m_lr, m_lb = _tracks(0.0, 0.0, np.random.default_rng(4), n=60)
    few = Matches(m_lb.left[:20], m_lb.other[:20], m_lb.affine, 20)
    start = (0.1, 0.0, 0.0, 0.0, 0.0)
    fit = _fit(m_lr, few, start=start)
    assert fit.tracks == 20 and not fit.significant
    assert fit.distortion == fit.start == start and fit.corner_sigma_px == np.inf
    assert fit.as_dict()["tracks"] == 20 and fit.as_dict()["corner_shift_sigma_px"] is None


def test_principal_points_apart_are_fitted_with_the_lens() -> None:
    # Three cameras, each bending its image about its own principal point (9-16 px
    # from the image centre, and from each other): bent about the image centre in
    # every view, the tracks read the lens off by more than the noise sigma says. Where
    # the principal points may differ (a prior of 10 px per camera), each view's centre
    # is fitted with the lens: recovered to a few px, and the bend with them.
    k1 = _k1_for_corner(0.003)
    shifted = {"left": (9.0, 6.0), "right": (12.0, -8.0), "back": (-10.0, 14.0)}
    tracks = _tracks(k1, 0.05, np.random.default_rng(5), pp=shifted)
    true = corner_shift_px(Lens(F, (W, H), (k1, 0, 0, 0, 0)))
    plain, fitted = _fit(*tracks), _fit(*tracks, pp_sigma_px=10.0)
    assert plain.centres_px == ((0.0, 0.0),) * 3  # one principal point: nothing to fit
    assert abs(plain.corner_px - true) > 2 * plain.corner_sigma_px
    assert fitted.significant
    for view, centre in zip(("left", "right", "back"), fitted.centres_px, strict=True):
        assert np.hypot(*np.subtract(centre, shifted[view])) < 5.0, view
    assert abs(fitted.corner_px - true) < 0.4 * abs(plain.corner_px - true)
    # The standard error still carries the principal points' prior (a consider term),
    # and the decision to take the lens weighs the noise alone.
    assert fitted.corner_noise_sigma_px == pytest.approx(plain.corner_sigma_px)
    assert fitted.corner_sigma_px > 1.5 * plain.corner_sigma_px
    assert fitted.offset_sigma_px >= plain.offset_sigma_px
    # The later stages bend each view about its own centre.
    back = fitted.lens(F, (W, H), 2)
    assert back.shift == fitted.centres_px[2] and back.distortion == fitted.distortion
    assert fitted.as_dict()["centres_px"]["right"] == [round(c, 2) for c in fitted.centres_px[1]]


def test_cluster_covariance_sees_errors_shared_within_blocks() -> None:
    # A line fitted to points whose errors share a random offset per spatial block
    # (shimmer moves patches together): the independent-residual covariance misses
    # most of the slope's spread, the cluster-robust one matches it.
    rng = np.random.default_rng(0)
    px = rng.uniform(0, 1000, (400, 2))
    labels = spatial_blocks(px, 4)
    J = np.c_[np.ones(len(px)), px[:, 0] / 1000]
    slopes, robust, independent = [], [], []
    for _ in range(300):
        errors = rng.normal(0, 1, 16)[labels] + rng.normal(0, 0.3, len(px))
        beta, *_ = np.linalg.lstsq(J, errors, rcond=None)
        r = errors - J @ beta
        slopes.append(beta[1])
        robust.append(np.sqrt(cluster_covariance(J, r, labels, 0)[1, 1]))
        independent.append(np.sqrt(np.linalg.inv(J.T @ J)[1, 1] * (r @ r) / (len(r) - 2)))
    spread = np.std(slopes)
    assert np.mean(robust) == pytest.approx(spread, rel=0.15)
    assert np.mean(independent) < 0.4 * spread


def test_correlated_track_errors_are_in_the_noise_sigma() -> None:
    # Shimmer-like errors (smooth fields, 0.3 px RMS, correlated over 30 px) in both
    # other views: the fitted corner's spread over draws against the sigma it reports.
    rng = np.random.default_rng(1)
    m_lr, m_lb = _tracks(0.0, 0.0, rng, n=800)
    corners, sigmas = [], []
    for _ in range(12):
        moved = [replace(m, other=m.other + _field_at(m.other, rng)) for m in (m_lr, m_lb)]
        fit = _fit(*moved)
        corners.append(fit.corner_px)
        sigmas.append(fit.corner_noise_sigma_px)
    # Measured: 0.73 of the spread (0.47 taking the errors as independent).
    assert np.mean(sigmas) > 0.6 * np.std(corners, ddof=1)


def test_the_offsets_share_is_how_far_a_wrong_lens_moves_the_yaw() -> None:
    # The lens's share of the offset's sigma is its corner sigma times how far the
    # right camera's yaw (the offset) moves when the lens is held wrong. Measured here
    # independently: the bundle refitted with k1 held either side of the fit's. Under
    # shimmer-like errors the cluster-robust covariance sets the sigma; its
    # correlations are how the noise moves yaw and lens together, not how one follows
    # the other (on this draw they gave 0.01 px per corner px against 2.2).
    rng = np.random.default_rng(3)
    m_lr, m_lb = (replace(m, other=m.other + _field_at(m.other, rng))
                  for m in _tracks(0.0, 0.0, rng, n=800))
    fit = _fit(m_lr, m_lb)
    lens = Lens(F, (W, H), (0.0,) * 5)
    _, back = rig_motion(m_lr, m_lb, F, lens.centre, three_view_tracks(m_lr, m_lb))
    z0, back_rotvec = back_view_start(back, 2.0)
    problem = Problem(lens, three_view_tracks(m_lr, m_lb), 2.0, 2.0, 1, 1 / z0, np.zeros((3, 2)))
    start = initial(problem, pseudo_rectify(m_lr, F, (W, H)), back_rotvec)
    p = least_squares(problem.residuals, start, x_scale=1e-3, diff_step=1e-6).x

    def yaw(k1_term: float) -> float:  # the right camera's yaw, the lens held at k1_term
        rest = least_squares(lambda q: problem.residuals(np.r_[k1_term, q]), p[1:],
                             x_scale=1e-3, diff_step=1e-6).x
        return float(rest[2])

    step = 1e-3  # of the corner radius: ~1 px at the corner
    per_term = (yaw(p[0] + step) - yaw(p[0] - step)) / (2 * step)  # rad
    offset_per_corner_px = abs(per_term) / corner_radius(lens)  # offset px per corner px
    assert fit.offset_sigma_px / fit.corner_sigma_px == pytest.approx(
        offset_per_corner_px, rel=0.02)


def _field_at(pts: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """A fresh shimmer field of the image, sampled at ``pts``: (N, 2) px."""
    dx, dy = shimmer_field((H, W), 0.3, 30.0, rng)
    m = pts.astype(np.float32).reshape(-1, 1, 2)
    return np.stack([cv2.remap(f, m[..., 0], m[..., 1], cv2.INTER_LINEAR).ravel()
                     for f in (dx, dy)], axis=1)


def _refine(m_lr: Matches, m_lb: Matches, start, pp_sigma_px: float = 0.0):
    lens = Lens(F, (W, H), start)
    rect = pseudo_rectify(m_lr, F, (W, H))
    return refine_lens(m_lr, m_lb, rect, lens, RIG, _settings(pp_sigma_px))


def test_a_profile_of_another_shape_is_rejected_and_the_lens_fitted_from_the_views() -> None:
    # The lens bends with k1 alone; the profile given is another lens's (k1, k2, k3 that
    # nearly cancel at the corner, like lensfun's P1000 at 71.9 mm on the example).
    k1 = _k1_for_corner(0.002)
    rc2 = (np.hypot(W - 1, H - 1) / 2 / F) ** 2
    profile = (8 * k1, -12 * k1 / rc2, 0.0, 0.0, 6 * k1 / rc2**2)
    tracks = _tracks(k1, 0.05, np.random.default_rng(4))
    fit = _refine(*tracks, start=profile)
    true = corner_shift_px(Lens(F, (W, H), (k1, 0, 0, 0, 0)))
    assert fit.start_rejected and fit.significant
    assert fit.distortion[1:] == (0.0, 0.0, 0.0, 0.0)  # k2, k3 of the profile dropped
    assert fit.corner_px == pytest.approx(true, abs=max(3 * fit.corner_sigma_px, 0.05 * true))
    assert "does not fit these frames" in str(fit.warning())
    # The right profile is kept, and nothing is said.
    kept = _refine(*tracks, start=(k1, 0, 0, 0, 0))
    assert not kept.start_rejected and kept.warning() is None


def test_a_profile_is_refined_in_k2_as_well() -> None:
    k1 = _k1_for_corner(0.003)
    rc2 = (np.hypot(W - 1, H - 1) / 2 / F) ** 2
    lens = (k1, -0.5 * k1 / rc2, 0.0, 0.0, 0.0)
    fit = _refine(*_tracks(k1, 0.05, np.random.default_rng(5)), start=lens)
    assert fit.fitted[1] != lens[1]  # k2 is a term the fit moves (k1 and k2 together)


def _clean_and_with_bad_back_tracks(share: float, px: float):
    """Fits on tracks of no distortion with 0.1 px noise, as they are and with a
    ``share`` of the back view's tracks moved by up to ``px`` px: (clean, bad)."""
    rng = np.random.default_rng(6)
    m_lr, m_lb = _tracks(0.0, 0.1, rng)
    bad = rng.random(len(m_lb.other)) < share
    moved = m_lb.other.copy()
    moved[bad] += rng.uniform(-px, px, (int(bad.sum()), 2))
    return _fit(m_lr, m_lb), _fit(m_lr, replace(m_lb, other=moved))


def test_tracks_that_fit_no_pose_do_not_inflate_the_lens_sigma() -> None:
    # Cars that moved between the captures: 8 % of the tracks land tens of px away.
    clean, fit = _clean_and_with_bad_back_tracks(0.08, 60)
    assert fit.corner_sigma_px < 2 * clean.corner_sigma_px
    assert not fit.significant


def test_bad_tracks_do_not_drag_the_fit_to_another_rig() -> None:
    # A tenth of the back view's tracks hundreds of px off: with the baseline and the
    # back camera's offset unbounded the first pass ran to a rig the tracks cannot
    # judge (the corner +- inf px); bounded, the fit stays at the truth.
    clean, fit = _clean_and_with_bad_back_tracks(0.1, 300)
    assert fit.corner_sigma_px < 2 * clean.corner_sigma_px
    assert abs(fit.corner_px) < 3 * clean.corner_sigma_px
    assert not fit.significant


def test_a_rejected_profile_is_fitted_again_as_if_none_were_given() -> None:
    # estimate_depth rectifies under the given lens to start the fit; once the views
    # reject that lens, the fit from nothing must not start from its rectification
    # (under lensfun's P1000 profile, 77 px at the corner, one field scene's fit from
    # nothing settled with 5x the tracks' RMS of the fit without a profile).
    k1 = _k1_for_corner(0.002)
    rc2 = (np.hypot(W - 1, H - 1) / 2 / F) ** 2
    profile = (30 * k1, -40 * k1 / rc2, 0.0, 0.0, 20 * k1 / rc2**2)
    m_lr, m_lb = _tracks(k1, 0.05, np.random.default_rng(8), pp={"back": (6.0, -9.0)})
    bent = Lens(F, (W, H), profile)
    under_profile = replace(m_lr, left=bent.to_ideal(m_lr.left), other=bent.to_ideal(m_lr.other))
    rect = pseudo_rectify(under_profile, F, (W, H))
    rejected = refine_lens(m_lr, m_lb, rect, bent, RIG, _settings(10.0))
    plain = _refine(m_lr, m_lb, (0.0,) * 5, pp_sigma_px=10.0)
    assert rejected.start_rejected and not plain.start_rejected
    assert rejected.corner_px == pytest.approx(plain.corner_px, abs=1e-6)
    assert np.allclose(rejected.centres_px, plain.centres_px, atol=1e-6)
