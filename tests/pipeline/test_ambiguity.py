"""The offset's standard error carries the principal points' uncertainty: the part it
adds must be what a real shift of the back view's principal point does to the fit."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from rigkit.pipeline.ambiguity import remove_ambiguity
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
    assert default.offset_sigma_px == pytest.approx(
        np.hypot(shared.offset_sigma_px, default.principal_point_sigma_px)
    )
