"""The offset's standard error carries the principal points' uncertainty: the part it
adds must be what a real shift of the back view's principal point does to the fit."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from rigkit.pipeline.ambiguity import (
    magnification_variance,
    remove_ambiguity,
    residual_shear_sq,
)
from rigkit.pipeline.features import match_views
from rigkit.pipeline.settings import PipelineSettings

SHIFT_PX = 8.0
DEFAULT = PipelineSettings()


@pytest.fixture(scope="module")
def back_matches(images):
    return match_views(images["left"], images["back"], "left/back")


def _ambiguity(m, result, rig, settings=DEFAULT):
    return remove_ambiguity(
        m, result.disparity, result.disparity_scale, result.rectification, rig, settings,
    )


def test_principal_point_term_predicts_the_effect_of_a_shifted_back_view(
    back_matches, result, rig
) -> None:
    s = PipelineSettings()
    base = _ambiguity(back_matches, result, rig, s)
    slope = []  # d offset / d shift along x and y, by central differences
    for axis in (0, 1):
        shift = np.zeros(2)
        shift[axis] = SHIFT_PX
        ahead, behind = (
            _ambiguity(replace(back_matches, other=back_matches.other + sign * shift),
                       result, rig, s).offset_px
            for sign in (1, -1)
        )
        slope.append((ahead - behind) / (2 * SHIFT_PX))
    # The term is |d offset / d shift| times the spread of the shift between two views.
    width = result.depth.shape[1]
    per_px = base.principal_point_sigma_px / (np.sqrt(2) * s.principal_point_sigma * width)
    assert np.hypot(*slope) == pytest.approx(per_px, rel=0.1)
    assert per_px > 1e-4  # a shifted back view does move the offset


def test_one_shared_principal_point_adds_nothing(back_matches, result, rig) -> None:
    shared = _ambiguity(back_matches, result, rig, PipelineSettings(principal_point_sigma=0))
    default = _ambiguity(back_matches, result, rig)
    assert shared.principal_point_sigma_px == 0.0
    assert shared.offset_px == default.offset_px  # the estimate itself is unchanged
    assert default.principal_point_sigma_px > 0  # three cameras' points add uncertainty
    assert default.offset_sigma_px > shared.offset_sigma_px


def test_residual_shear_is_recovered_from_noisy_residuals() -> None:
    rng = np.random.default_rng(5)
    px = rng.uniform(0, 4000, (3000, 2))
    centred = px - px.mean(axis=0)
    # A shear (2e-4, -1e-4), a turn and a magnification (which poses absorb, not shears).
    A = np.array([[2e-4 + 3e-4, -1e-4 - 4e-4], [-1e-4 + 4e-4, -2e-4 + 3e-4]])
    residuals = centred @ A.T + rng.normal(0, 0.3, px.shape)
    assert residual_shear_sq(px, residuals) == pytest.approx(5e-8, rel=0.1)
    # Noise alone: its scatter's share is taken off, nothing is left.
    assert residual_shear_sq(px, rng.normal(0, 0.3, px.shape)) < 2e-11


def test_magnification_variance_pools_three_modes_of_the_air() -> None:
    # Second derivatives of an isotropic phase screen at the frame's scale: var(phi_xx) =
    # var(phi_yy) = 3c, var(phi_xy) = c, cov(phi_xx, phi_yy) = c (c = 1 here); the right
    # view shows the stretch phi_yy, the back view the two shears, and the offset's error
    # is the magnification (phi_xx + phi_yy) / 2.
    rng = np.random.default_rng(11)
    xx, yy = rng.multivariate_normal([0, 0], [[3, 1], [1, 3]], 200_000).T
    xy = rng.normal(0, 1, xx.size)
    magnification = (xx + yy) / 2
    shear_sq = ((xx - yy) / 2) ** 2 + xy**2
    pooled = magnification_variance(yy**2, shear_sq)
    stretch_only = magnification_variance(yy**2, 0.0) * 3  # the stretch alone, 2/3 of it
    assert np.mean(pooled) == pytest.approx(np.var(magnification), rel=0.02)  # unbiased
    assert np.mean(stretch_only) == pytest.approx(np.var(magnification), rel=0.02)
    # One frame, one draw: a 2 sigma interval from the pooled estimate misses less often.
    missed_pooled = np.mean(np.abs(magnification) > 2 * np.sqrt(pooled))
    missed_stretch = np.mean(np.abs(magnification) > 2 * np.sqrt(stretch_only))
    assert missed_pooled < 0.6 * missed_stretch
