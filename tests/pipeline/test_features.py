"""Stage 0: a left image prepared once matches each view as it would on its own."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from rigkit.errors import PipelineError
from rigkit.pipeline.features import (
    _check_alignment,
    _ratio_matches,
    local_contrast,
    match_all,
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


def _whole_image_contrast(image: np.ndarray, window: int = 31) -> np.ndarray:
    """local_contrast as it was computed before it went in strips: on whole images."""
    h, w = image.shape
    outside = np.isnan(image)
    cut = bool(outside.any())
    values = np.where(outside, np.float32(0), image) if cut else image
    half, box = (max(1, w // 2), max(1, h // 2)), (window // 2 | 1, window // 2 | 1)

    def local_mean(a: np.ndarray) -> np.ndarray:
        return cv2.boxFilter(cv2.resize(a, half, interpolation=cv2.INTER_AREA), -1, box)

    mean, square = local_mean(values), local_mean(cv2.multiply(values, values))
    if cut:
        seen = np.maximum(local_mean((~outside).astype(np.float32)), np.float32(1e-6))
        mean, square = cv2.divide(mean, seen), cv2.divide(square, seen)
    spread = cv2.sqrt(np.maximum(cv2.subtract(square, cv2.multiply(mean, mean)), np.float32(1e-3)))
    mean, spread = (cv2.resize(a, (w, h), interpolation=cv2.INTER_LINEAR) for a in (mean, spread))
    z = cv2.divide(cv2.subtract(values, mean), spread, scale=32.0)
    out = cv2.add(z, 128.0, dtype=cv2.CV_8U)  # type: ignore[call-overload]
    out[outside] = 128
    return out


@pytest.mark.parametrize("size", [(384, 384), (250, 384), (77, 384), (383, 384), (2, 40)])
def test_local_contrast_in_strips_is_the_whole_image_computation(size) -> None:
    rng = np.random.default_rng(1)
    texture = (150 + 5 * plane_waves((0, 0))[: size[0], : size[1]]
               + rng.normal(0, 1, size)).astype(np.float32)
    assert np.array_equal(local_contrast(texture), _whole_image_contrast(texture))
    cut = texture.copy()
    cut[:, :30] = np.nan
    cut[size[0] // 3 :, -20:] = np.nan
    whole = _whole_image_contrast(cut)
    assert np.array_equal(local_contrast(cut), whole)
    assert np.isnan(cut).any()  # left as it was
    assert np.array_equal(local_contrast(cut.copy(), overwrite=True), whole)


def test_ratio_matches_are_opencvs_brute_force_knn() -> None:
    left = (150 + 40 * plane_waves((0, 0), (500, 500))).clip(0, 255).astype(np.uint8)
    other = (150 + 40 * plane_waves((7.3, -4.1), (500, 500))).clip(0, 255).astype(np.uint8)
    sift = cv2.SIFT_create(nfeatures=4000, contrastThreshold=0.01)  # type: ignore[attr-defined]
    (_, d1), (_, d2) = sift.detectAndCompute(left, None), sift.detectAndCompute(other, None)
    knn = cv2.BFMatcher(cv2.NORM_L2).knnMatch(d1, d2, k=2)
    good = [m[0] for m in knn if len(m) == 2 and m[0].distance < 0.8 * m[1].distance]
    assert len(good) > 100
    for a, b in ((d1, d2), (d1 + np.float32(0.25), d2)):  # SIFT's whole numbers, and not
        query, train = _ratio_matches(a, b)
        if a is not d1:
            knn = cv2.BFMatcher(cv2.NORM_L2).knnMatch(a, b, k=2)
            good = [m[0] for m in knn if len(m) == 2 and m[0].distance < 0.8 * m[1].distance]
        assert query.tolist() == [m.queryIdx for m in good]
        assert train.tolist() == [m.trainIdx for m in good]


def test_matching_both_views_at_once_is_matching_each_alone() -> None:
    left = (150 + 20 * plane_waves((0, 0))).astype(np.float32)
    right = (150 + 20 * plane_waves((3.3, 0.2))).astype(np.float32)
    back = (150 + 20 * plane_waves((-1.6, 2.7))).astype(np.float32)
    both = match_all(left, [(right, "left/right"), (back, "left/back")], n_points=400)
    before = cv2.getNumThreads()
    cv2.setNumThreads(1)  # one thread: the views in turn
    try:
        serial = match_all(left, [(right, "left/right"), (back, "left/back")], n_points=400)
    finally:
        cv2.setNumThreads(before)
    ref = prepare_left(left, n_points=400)
    for m, s, other in zip(both, serial, (right, back), strict=True):
        alone = match_to(ref, other)
        for a in (m, s):
            assert np.array_equal(a.left, alone.left) and np.array_equal(a.other, alone.other)


def test_a_view_no_affine_map_predicts_is_tracked_everywhere() -> None:
    """Ground receding up the view shifts its near part by tens of px more than an
    affine map fitted to the rest; those corners are searched for where the feature
    matches put them, and found to the precision of the others."""
    from rigkit.synth.render import sample_texture
    from rigkit.synth.shapes import TextureMap

    h, w = 768, 1024
    tex = TextureMap("camera", 1.3, 17.0, (40.0, 60.0), 5)
    yy, xx = np.mgrid[0:h, 0:w].astype(np.float64)
    # the bottom 35 % is nearer ground, ramping from 60 to 75 px more disparity
    dx = np.where(yy < 0.65 * h, 6.0, 66.0 + 0.05 * (yy - 0.65 * h))
    left = (255 * sample_texture(tex, xx, yy)).astype(np.float32)
    right = (255 * sample_texture(tex, xx + dx, yy)).astype(np.float32)  # x' = x - dx
    m = match_views(left, right, "left/right")
    bottom = m.left[:, 1] > 0.7 * h
    assert bottom.sum() > 50  # none there when searched from the affine map's prediction
    truth = m.left[:, 0] - np.interp(m.left[:, 1], yy[:, 0], dx[:, 0])
    assert np.median(np.abs(m.other[:, 0] - truth)) < 0.05
