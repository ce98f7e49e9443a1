"""Views that disagree: a scene whose cars and people stand elsewhere in each view
(rigkit synth's movers, with the ground truth of what they cover) gets no confident
depth where they are, and the checks it rests on recover a known truth."""

from __future__ import annotations

from dataclasses import replace

import cv2
import numpy as np
import pytest

from rigkit.imagefile.decode import load_grey
from rigkit.pipeline import RigGeometry, estimate_depth
from rigkit.pipeline.agreement import (
    SHIMMER_STEP_MAX_PX,
    back_positions,
    right_at_disparity,
    shimmer_steps,
    zncc,
)
from rigkit.pipeline.estimate import FLAG_DISAGREE, FLAG_FILLED, FLAG_MATCHED
from rigkit.pipeline.settings import PipelineSettings
from rigkit.pipeline.stereo import fill_holes
from rigkit.synth import SynthParams, generate_scene, load_scene, write_scene

MOVING = SynthParams(width=960, height=720, n_movers=12, noise_dn=1.0)


@pytest.fixture(scope="module")
def town(tmp_path_factory):
    out = tmp_path_factory.mktemp("movers") / "town"
    write_scene(generate_scene(MOVING, 4), out)
    truth = load_scene(out)
    images = [load_grey(truth.image_path(v)) for v in ("left", "right", "back")]
    rig = RigGeometry(truth.focal_px, truth.baseline_lr_m, truth.baseline_lb_m)
    return truth, images, rig


def _wrong_moved(truth, depth: np.ndarray) -> float:
    """Share of the moved left pixels given a depth more than 3 % off."""
    moved, _ = truth.changes()
    gt = truth.depth("left")
    moved &= np.isfinite(gt)
    with np.errstate(invalid="ignore"):
        wrong = np.abs(depth / gt - 1) > 0.03
    return float((moved & wrong).sum() / moved.sum())


def test_moved_pixels_get_no_confident_depth(town) -> None:
    truth, images, rig = town
    checked = estimate_depth(*images, rig)
    unchecked = estimate_depth(*images, rig, settings=PipelineSettings(min_agreement=0.0))
    moved, _ = truth.changes()
    assert moved.mean() > 0.01  # the scene has something that moved
    # Without the check, semi-global matching gives many moved pixels a wrong depth.
    assert _wrong_moved(truth, unchecked.depth) > 0.04
    assert _wrong_moved(truth, checked.depth) < 0.5 * _wrong_moved(truth, unchecked.depth)
    # Most of what the check removes is where something moved, or beside it (the
    # margin, and the edge of what a mover hid).
    flagged = checked.disagree & np.isfinite(unchecked.depth)
    near = cv2.dilate(moved.astype(np.uint8), np.ones((21, 21), np.uint8)) > 0
    assert (flagged & near).sum() > 0.6 * flagged.sum()
    assert np.isnan(checked.depth[checked.disagree]).all()
    assert checked.diagnostics()["views_disagree_fraction"] == pytest.approx(
        checked.disagree.mean())


def test_flags_say_what_each_depth_rests_on(town) -> None:
    _, images, rig = town
    result = estimate_depth(*images, rig)
    flags = result.flags()
    assert flags.dtype == np.uint8 and flags.shape == result.depth.shape
    has = np.isfinite(result.depth)
    assert np.all((flags[has] & (FLAG_MATCHED | FLAG_FILLED)) > 0)
    assert np.all(flags[result.disagree] & FLAG_DISAGREE)
    assert np.all((flags[result.filled & has] & FLAG_FILLED) > 0)
    assert not np.any(flags[~has] & (FLAG_MATCHED | FLAG_FILLED))


def test_the_views_agree_where_the_world_stands_still(images, rig, result) -> None:
    # The static fixture scene: its own depth predicts what the right and the back
    # camera see (high ZNCC), and little is refused.
    assert result.disagree.mean() < 0.02
    s = result.settings
    scale = result.disparity_scale
    xs, ys = back_positions(result.disparity, scale, result.rectification, result.ambiguity,
                            _lens(result, images), rig.baseline_lr_m, rig.baseline_lb_m)
    small = cv2.resize(images["back"], None, fx=scale, fy=scale, interpolation=cv2.INTER_AREA)
    back = cv2.remap(small, xs, ys, cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT,
                     borderValue=np.nan)
    assert np.isfinite(back).mean() > 0.5
    assert s.min_agreement == 0.5


def _lens(result, images):
    from rigkit.pipeline.lens import Lens

    h, w = images["left"].shape
    return Lens(float(result.rectification.K[0, 0]), (w, h), result.distortion)


def test_right_at_disparity_samples_the_match() -> None:
    rng = np.random.default_rng(1)
    right = rng.uniform(0, 255, (20, 40)).astype(np.float32)
    disparity = np.full((20, 40), 3.0, np.float32)
    disparity[5, 7] = np.nan
    seen = right_at_disparity(right, disparity)
    assert seen[4, 10] == pytest.approx(right[4, 7])
    assert np.isnan(seen[5, 7]) and np.isnan(seen[0, 1])  # no disparity; off the image


def test_zncc_is_one_for_the_same_window_and_blind_to_gain() -> None:
    rng = np.random.default_rng(2)
    a = rng.uniform(0, 255, (30, 30)).astype(np.float32)
    assert zncc(a, 0.5 * a + 40, 7)[15, 15] == pytest.approx(1.0, abs=1e-4)
    assert zncc(a, 255 - a, 7)[15, 15] == pytest.approx(-1.0, abs=1e-4)
    other = rng.uniform(0, 255, (30, 30)).astype(np.float32)
    assert abs(zncc(a, other, 7)[15, 15]) < 0.6
    assert zncc(a, np.full_like(a, 9.0), 7)[15, 15] == 0.0  # a flat window: no evidence


def test_zncc_compares_only_what_the_other_view_sees() -> None:
    # A window that straddles the edge of what the other view sees (its frame, or
    # pixels with no disparity) is compared on its seen part: the unseen part must
    # not read as a change, whatever the other camera's gain.
    rng = np.random.default_rng(3)
    a = rng.uniform(0, 255, (30, 30)).astype(np.float32)
    b = 0.5 * a + 40
    b[:, 16:] = np.nan  # the other view ends beside the pixel
    assert zncc(a, b, 9)[15, 15] == pytest.approx(1.0, abs=1e-4)
    changed = b.copy()
    changed[:, :16] = rng.uniform(0, 255, (30, 16))  # what it sees is something else
    assert zncc(a, changed, 9)[15, 15] < 0.6
    assert np.isfinite(zncc(a, b, 9)[15, 18])  # 2 of its 9 columns seen
    assert np.isnan(zncc(a, b, 9)[15, 19])  # 1 of 9: under MIN_SEEN_SHARE
    few = np.full_like(a, np.nan)
    few[15, 15] = 1.0
    assert np.isnan(zncc(a, few, 9)[15, 15])  # one pixel of 81: no evidence


def _scene(tmp_path_factory, params: SynthParams, seed: int):
    out = tmp_path_factory.mktemp("air") / "scene"
    write_scene(generate_scene(params, seed), out)
    truth = load_scene(out)
    images = [load_grey(truth.image_path(v)) for v in ("left", "right", "back")]
    return truth, images, RigGeometry(truth.focal_px, truth.baseline_lr_m, truth.baseline_lb_m)


def test_midday_air_does_not_refuse_a_still_world(tmp_path_factory) -> None:
    # 1 px of shimmer per view (single frames): a right depth puts the other views'
    # windows off by about that much. Compared at the depth's own position only, 8.2 %
    # of this scene was refused; within the views' measured misalignment, 0.7 %.
    truth, images, rig = _scene(tmp_path_factory, SynthParams(width=960, height=720,
                                                              shimmer_px=1.0), 2)
    result = estimate_depth(*images, rig)
    assert result.ambiguity.rms_px > 1.0  # the air moved the views that much
    assert result.disagree.mean() < 0.02


def test_what_moved_is_still_refused_in_midday_air(tmp_path_factory) -> None:
    # The tolerance is one misalignment step: cars and people are metres away.
    truth, images, rig = _scene(tmp_path_factory, replace(MOVING, shimmer_px=1.0), 6)
    checked = estimate_depth(*images, rig)
    unchecked = estimate_depth(*images, rig, settings=PipelineSettings(min_agreement=0.0))
    assert _wrong_moved(truth, checked.depth) < 0.5 * _wrong_moved(truth, unchecked.depth)


def test_shimmer_steps_follow_the_measured_misalignment() -> None:
    assert shimmer_steps(0.4, 0.5, axes=2) == [(0.0, 0.0)]  # 0.2 canvas px: in place
    assert shimmer_steps(float("nan"), 0.5, axes=2) == [(0.0, 0.0)]
    steps = shimmer_steps(1.2, 0.5, axes=2)
    assert len(steps) == 9 and (0.0, 0.0) in steps and (0.6, -0.6) in steps
    assert shimmer_steps(1.2, 0.5, axes=1) == [(0.0, -0.6), (0.0, 0.0), (0.0, 0.6)]
    assert max(dy for _, dy in shimmer_steps(50.0, 0.5, axes=1)) == SHIMMER_STEP_MAX_PX


def test_holes_are_not_filled_across_a_barrier() -> None:
    row = np.array([[5.0, np.nan, np.nan, 9.0, 9.0, np.nan, np.nan, 4.0]], np.float32)
    filled, holes = fill_holes(row, 8)
    assert holes[0, 1] and filled[0, 1] == 5.0 and filled[0, 6] == 4.0
    barrier = np.zeros(row.shape, bool)
    barrier[0, 6] = True  # the views disagree there
    filled, holes = fill_holes(row, 8, barrier=barrier)
    assert filled[0, 1] == 5.0  # a gap between two matched pixels is filled as before
    assert np.isnan(filled[0, 5]) and np.isnan(filled[0, 6]) and not holes[0, 5]


def test_agreement_settings_are_validated() -> None:
    with pytest.raises(ValueError, match="min_agreement"):
        PipelineSettings(min_agreement=1.5)
    with pytest.raises(ValueError, match="agreement_window_px"):
        replace(PipelineSettings(), agreement_window_px=1)
