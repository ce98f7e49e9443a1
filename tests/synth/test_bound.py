"""The offset's bound under heat shimmer: its covariance must be the renderer's, its
estimators' spreads what they do on draws of that noise, and on a rendered scene the
spread it predicts for the pipeline's fit the one that fit has."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from rigkit.errors import InputError
from rigkit.imagefile.decode import load_grey
from rigkit.pipeline import RigGeometry, estimate_depth
from rigkit.pipeline.ambiguity import remove_ambiguity
from rigkit.pipeline.features import match_views
from rigkit.synth import SynthParams, field_params, generate_scene, load_scene, write_scene
from rigkit.synth.bound import (
    exact_tracks,
    gaussian_correlation,
    gls_covariance,
    offset_bound,
    ols_covariance,
    shimmer_covariance,
    vonkarman_correlation,
)
from rigkit.synth.evaluate import visible_in_right
from rigkit.synth.shimmer import shimmer_field, vonkarman_field

RMS, CORR = 0.3, 6.0


def test_covariance_is_the_renderers_shimmer() -> None:
    """Two frames' fields at the same points: twice one field's autocovariance."""
    rng = np.random.default_rng(0)
    lags = (0, 6, 12)
    measured = np.zeros(len(lags))
    for _ in range(8):
        dx, _ = shimmer_field((240, 320), RMS, CORR, rng)
        measured += [np.mean(dx[:, : dx.shape[1] - r] * dx[:, r:]) for r in lags]
    measured /= 8
    pts = np.array([[0.0, 0.0], [6.0, 0.0], [12.0, 0.0]])
    model = shimmer_covariance(pts, pts, RMS, gaussian_correlation(CORR), tracker_px=0.0)[0]
    assert model == pytest.approx(2 * measured, abs=0.05 * RMS**2)


def test_von_karman_covariance_is_the_renderers_shimmer() -> None:
    """The Matérn form against drawn von Karman fields (correlation 0.44 at a fifth of
    the outer scale, 0.15 at two fifths, none at 1.2); averaged over a burst of 5
    frames, a fifth of it."""
    outer, lags = 100.0, (0, 20, 40, 120)
    rng = np.random.default_rng(3)
    measured = np.zeros(len(lags))
    draws = 24
    for _ in range(draws):
        dx, _ = vonkarman_field((480, 640), RMS, outer, rng)
        measured += [np.mean(dx[:, : dx.shape[1] - r] * dx[:, r:]) for r in lags]
    measured /= draws
    pts = np.array([[float(r), 0.0] for r in lags])
    rho = vonkarman_correlation(outer)
    model = shimmer_covariance(pts, pts, RMS, rho, tracker_px=0.0)[0]
    assert model == pytest.approx(2 * measured, abs=0.05 * RMS**2)
    burst = shimmer_covariance(pts, pts, RMS, rho, tracker_px=0.0, frames=5)[0]
    assert burst == pytest.approx(model / 5)


def _line_model(n: int = 40) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Points along 400 px, a shift and a scale per axis: (points, J (2n, 3), cov)."""
    x = np.linspace(0, 400, n)
    pts = np.stack([x, np.zeros(n)], axis=1)
    J = np.zeros((2 * n, 3))
    J[0::2, 0] = 1.0  # a shift in u
    J[0::2, 2] = J[1::2, 2] = x / 400  # a scale, seen in both axes
    J[1::2, 1] = 1.0  # a shift in v
    J[1::2, 2] *= np.linspace(-1, 1, n) ** 2
    return pts, J, shimmer_covariance(pts, pts + 50, RMS, gaussian_correlation(40.0))


def test_estimator_covariances_are_their_spreads_on_correlated_noise() -> None:
    pts, J, cov = _line_model()
    L = np.linalg.cholesky(cov)
    rng = np.random.default_rng(1)
    draws = 3000
    noise = np.empty((draws, J.shape[0]))
    noise[:, 0::2] = rng.standard_normal((draws, len(pts))) @ L.T
    noise[:, 1::2] = rng.standard_normal((draws, len(pts))) @ L.T
    ols = np.linalg.lstsq(J, noise.T, rcond=None)[0]
    W = np.linalg.inv(cov)
    info = sum(J[a::2].T @ W @ J[a::2] for a in range(2))
    gls = np.linalg.solve(info, sum(J[a::2].T @ W @ noise.T[a::2] for a in range(2)))
    ols_sigma = np.sqrt(np.diag(ols_covariance(J, cov)))
    gls_sigma = np.sqrt(np.diag(gls_covariance(J, cov.copy())))
    assert ols.std(axis=1) == pytest.approx(ols_sigma, rel=0.06)
    assert gls.std(axis=1) == pytest.approx(gls_sigma, rel=0.06)
    # The correlated noise is what makes them differ: the scale is better weighted.
    assert gls_sigma[2] < 0.9 * ols_sigma[2]


def test_with_independent_errors_both_are_the_textbook_covariance() -> None:
    pts, J, _ = _line_model()
    white = shimmer_covariance(pts, pts, 0.0, gaussian_correlation(1.0), tracker_px=0.2)
    textbook = 0.04 * np.linalg.inv(J.T @ J)
    assert ols_covariance(J, white) == pytest.approx(textbook)
    assert gls_covariance(J, white.copy()) == pytest.approx(textbook)


def _at(field: tuple[np.ndarray, np.ndarray], px: np.ndarray) -> np.ndarray:
    """(N, 2): a displacement field's (dx, dy) at the pixels nearest ``px`` (N, 2)."""
    u, v = np.rint(px).astype(int).T
    return np.stack([field[0][v, u], field[1][v, u]], axis=1)


@pytest.fixture(scope="module")
def shimmered(tmp_path_factory):
    """A small field scene (sky, haze, 0.3 px shimmer) and the pipeline's result."""
    params = replace(field_params(SynthParams(width=640, height=480)), max_pp_offset_px=0.0)
    out = tmp_path_factory.mktemp("bound") / "seed-7"
    write_scene(generate_scene(params, seed=7), out)
    truth = load_scene(out)
    images = [load_grey(truth.image_path(v)) for v in ("left", "right", "back")]
    rig = RigGeometry(truth.focal_px, truth.baseline_lr_m, truth.baseline_lb_m)
    return truth, images, rig, estimate_depth(*images, rig)


@pytest.mark.slow
def test_predicted_spread_is_the_fits_spread_over_shimmer_draws(shimmered) -> None:
    """Exact back positions moved by fresh shimmer fields, refitted: the offset spreads
    as the bound's ``estimator_px`` says; and the best estimator does better."""
    truth, (left, _, back), rig, result = shimmered
    m = match_views(left, back, "left/back")
    bound = offset_bound(truth, result, m.left, step_px=12.0)
    kept, _, _, exact = exact_tracks(truth, result, m.left, visible_in_right(truth))
    m = replace(m, left=kept, other=exact)
    rng = np.random.default_rng(2)
    corr = truth.params.shimmer_corr_px
    offsets = []
    for _ in range(40):
        in_left = _at(shimmer_field(left.shape, RMS, corr, rng), m.left)
        in_back = _at(shimmer_field(back.shape, RMS, corr, rng), m.other)
        amb = remove_ambiguity(replace(m, other=m.other + in_back - in_left),
                               result.disparity, result.disparity_scale,
                               result.rectification, rig)
        offsets.append(amb.offset_px)
    assert np.std(offsets, ddof=1) == pytest.approx(bound.estimator_px, rel=0.2)
    # Weighting by the covariance can only help on the same points (Gauss-Markov).
    assert bound.bound_px <= bound.surface_px
    assert bound.bound_px < bound.estimator_px
    assert bound.grid_points > bound.matches


def test_a_scene_without_shimmer_has_no_bound(truth, result) -> None:
    with pytest.raises(InputError, match="no heat shimmer"):
        offset_bound(truth, result, np.zeros((10, 2)))


def test_fine_shimmer_has_no_bound(truth, result) -> None:
    params = replace(truth.params, shimmer_px=0.3, shimmer_spectrum="fine")
    with pytest.raises(InputError, match="gaussian and vonkarman shimmer only, not of fine"):
        offset_bound(replace(truth, params=params), result, np.zeros((10, 2)))


def test_a_grid_coarser_than_the_image_is_refused(shimmered) -> None:
    truth, (left, _, back), _, result = shimmered
    m = match_views(left, back, "left/back")
    with pytest.raises(InputError, match="points on the surface"):
        offset_bound(truth, result, m.left, step_px=10_000.0)
