"""Stage 0: a left image prepared once matches each view as it would on its own."""

from __future__ import annotations

import numpy as np

from rigkit.pipeline.features import brightness_gain, match_to, match_views, prepare_left


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
