"""Evaluation on estimates with known, injected errors."""

from __future__ import annotations

import numpy as np
import pytest

from rigkit.errors import InputError
from rigkit.synth.evaluate import depth_metrics, evaluate_scenes, format_table, visible_in_right


@pytest.fixture(scope="module")
def judged(truth):
    return visible_in_right(truth)


def test_ground_truth_scores_perfectly(truth, judged) -> None:
    gt = truth.depth("left")
    m = depth_metrics(gt, gt, judged)
    assert m.under_0_5 == m.under_1 == m.under_3 == m.density == 1.0 and m.median_bias == 0


def test_scaled_depth_falls_between_thresholds(truth, judged) -> None:
    gt = truth.depth("left")
    m = depth_metrics(gt * 1.015, gt, judged)
    assert m.under_1 == 0.0 and m.under_2 == 1.0
    assert m.median_bias == pytest.approx(0.015, abs=1e-6)


def test_missing_pixels_count_as_misses(truth, judged) -> None:
    gt = truth.depth("left")
    est = gt.copy()
    est[: gt.shape[0] // 2] = np.nan
    m = depth_metrics(est, gt, judged)
    expected = judged[gt.shape[0] // 2 :].sum() / judged.sum()
    assert m.density == pytest.approx(expected) and m.under_1 == pytest.approx(expected)


def test_visibility_excludes_what_the_right_camera_cannot_see(truth, judged) -> None:
    # The right camera is rotated and 2 m to the side: part of the left view is unseen,
    # but most of it is seen.
    assert 0.3 < judged.mean() < 0.999


def test_missing_estimate_is_a_failure(scene_dir, tmp_path) -> None:
    rows = evaluate_scenes([scene_dir], tmp_path)
    assert rows[0].failed and "no depth estimate" in rows[0].reason
    assert "failures: 1 of 1" in format_table(rows)


def test_wrong_shape_is_an_input_error(truth, judged) -> None:
    gt = truth.depth("left")
    with pytest.raises(InputError, match="ground truth is"):
        depth_metrics(gt[:-1], gt, judged)
