"""Stage 0: a left image prepared once matches each view as it would on its own."""

from __future__ import annotations

import numpy as np
import pytest

from rigkit.errors import PipelineError
from rigkit.pipeline.checks import affine_scale
from rigkit.pipeline.features import (
    _check_alignment,
    brightness_gain,
    match_to,
    match_views,
    prepare_left,
)


@pytest.mark.slow
def test_prepared_left_matches_both_views_as_on_its_own(images) -> None:
    ref = prepare_left(images["left"])
    for view in ("right", "back"):
        alone = match_views(images["left"], images[view], f"left/{view}")
        shared = match_to(ref, images[view], f"left/{view}")
        assert len(alone.left) > 500
        assert np.array_equal(shared.left, alone.left)
        assert np.array_equal(shared.other, alone.other)


def test_brightness_gain_undoes_exposure_and_vignetting_but_not_noise(images) -> None:
    reference = images["left"]
    h, w = reference.shape
    yy, xx = np.mgrid[0:h, 0:w]
    r2 = ((xx - w / 2) ** 2 + (yy - h / 2) ** 2) / (w / 2) ** 2
    shading = (0.6 * (1 - 0.3 * r2)).astype(np.float32)  # darker, vignetted
    noise = np.random.default_rng(0).normal(0, 5, (h, w)).astype(np.float32)
    image = np.clip(reference * shading + noise, 0, None)
    image[:, : w // 4] = 0  # outside its footprint: left out of the means
    gain = brightness_gain(image, reference)
    inner = (slice(h // 8, -h // 8), slice(w // 4 + w // 8, -w // 8))
    assert np.abs(gain[inner] * shading[inner] - 1).max() < 0.03
    # Smooth: it follows neither the noise nor the texture (second differences).
    assert np.abs(np.diff(gain[inner], 2, axis=1)).max() < 1e-4


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
