"""Stage 0: a left image prepared once matches each view as it would on its own."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from rigkit.errors import PipelineError
from rigkit.pipeline.checks import affine_scale
from rigkit.pipeline.features import (
    _check_alignment,
    local_contrast,
    match_to,
    match_views,
    prepare_left,
)
from tests.pipeline.textures import plane_waves


@pytest.mark.slow
def test_prepared_left_matches_both_views_as_on_its_own(images) -> None:
    ref = prepare_left(images["left"])
    for view in ("right", "back"):
        alone = match_views(images["left"], images[view], f"left/{view}")
        shared = match_to(ref, images[view], f"left/{view}")
        assert len(alone.left) > 500
        assert np.array_equal(shared.left, alone.left)
        assert np.array_equal(shared.other, alone.other)


def test_tracks_hold_through_a_cloud_shadow_in_haze() -> None:
    # Hazy texture 5 grey levels deep; in the other view the left half lies under a
    # cloud shadow, which halves the sunlit texture but not the haze, and the exposure
    # differs. Matching the mean alone kept 25 of the shadowed half's corners.
    shift = (0.3, -0.2)
    left = (150 + 5 * plane_waves((0, 0))).astype(np.float32)
    shade = np.ones((384, 384))
    shade[:, :192] = 0.5
    shade = cv2.GaussianBlur(shade, (0, 0), 20)
    other = (0.9 * (150 + 5 * plane_waves(shift) * shade)).astype(np.float32)
    ref = prepare_left(left, n_points=400)
    m = match_to(ref, other, "left/back")
    shadowed = m.left[:, 0] < 192
    assert shadowed.sum() > 0.8 * (ref.corners[:, 0] < 192).sum()
    error = m.other - m.left + np.array(shift)  # the texture at x appears at x - shift
    assert np.abs(error).max() < 0.06
    assert np.sqrt(np.mean(error**2)) < 0.025


def test_local_contrast_ignores_gain_offset_and_the_unseen() -> None:
    texture = (150 + 5 * plane_waves((0, 0))).astype(np.float32)
    plain = local_contrast(texture).astype(int)
    assert plain.std() > 20  # spread over the levels, not 5 of them
    dimmer = local_contrast((0.6 * texture - 40).astype(np.float32)).astype(int)
    assert np.abs(dimmer - plain).max() <= 1
    cut = texture.copy()
    cut[:, :100] = np.nan  # outside the view's footprint
    seen = local_contrast(cut).astype(int)
    assert (seen[:, :100] == 128).all()
    # Next to the cut, the means are over what is seen: no step at its edge.
    assert np.abs(seen[:, 100:] - plain[:, 100:]).mean() < 2


def test_an_alignment_no_rig_gives_is_refused() -> None:
    half_turn = np.array([[-1.0, 0.0, 900.0], [0.0, -1.0, 700.0]])
    with pytest.raises(PipelineError, match="turned by 180 deg"):
        _check_alignment(half_turn, "left/right")
    mirror = np.array([[-1.0, 0.0, 900.0], [0.0, 1.0, 0.0]])
    with pytest.raises(PipelineError, match="no rig gives"):
        _check_alignment(mirror, "left/back")
    _check_alignment(np.array([[0.993, -0.05, 3.0], [0.05, 0.993, -2.0]]), "left/back")


def test_scale_of_a_view_is_read_along_the_columns() -> None:
    # A facade turned away from the rig compresses the right view along the rows only.
    assert affine_scale(np.array([[0.981, 0.0, 0.0], [0.0, 1.0, 0.0]])) == pytest.approx(1.0)
    turned = 0.993 * np.array([[np.cos(0.1), -np.sin(0.1), 0], [np.sin(0.1), np.cos(0.1), 0]])
    assert affine_scale(turned) == pytest.approx(0.993)
