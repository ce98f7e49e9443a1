"""Scenes with depth (issue 47): ground receding up the view, seen by level cameras with
sky above the rim, and a scene with little relief. Each was refused before the views'
scales followed the geometry (pipeline/motion.py): "were right and back swapped?" and
"little depth in view"."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from rigkit.imagefile.decode import load_grey
from rigkit.pipeline import RigGeometry, estimate_depth
from rigkit.synth import SynthParams, generate_scene, load_scene, write_scene
from rigkit.synth.evaluate import depth_metrics, offset_error_px, visible_in_right

SIZE = {"width": 768, "height": 576}


def _run(tmp: Path, params: SynthParams, seed: int):
    write_scene(generate_scene(params, seed), tmp)
    truth = load_scene(tmp)
    images = [load_grey(truth.image_path(v)) for v in ("left", "right", "back")]
    result = estimate_depth(*images, RigGeometry(truth.focal_px, 2.0, 2.0))
    judged = visible_in_right(truth)
    metrics = depth_metrics(result.depth, truth.depth("left"), judged)
    return truth, result, metrics


@pytest.mark.slow
def test_a_valley_seen_from_a_level_tripod(tmp_path: Path) -> None:
    # 215-300 m up the view, the rim 40 % below the top; the back camera 0.3 m higher
    # stretched an affine map of the back view by more than its magnification
    params = SynthParams(**SIZE, backdrop="ground", depth_ratio=1.8, sky=0.45)
    truth, result, metrics = _run(tmp_path, params, 5)
    ground = truth.depth("left")
    assert np.nanpercentile(ground, 99) / np.nanpercentile(ground, 1) > 1.3
    assert metrics.under_1 > 0.93  # 94.4 % at 768 px
    assert abs(metrics.median_bias) < 0.003
    error = offset_error_px(truth, result.depth, truth.focal_px)
    assert abs(error) < 2 * result.ambiguity.offset_sigma_px
    assert result.relief_warning() is None  # tens of px of parallax


@pytest.mark.slow
def test_little_relief_is_measured_not_refused(tmp_path: Path) -> None:
    # relief spreading the disparities by ~0.46 px at 768 px: its range comes from the
    # back view's magnification, which the run says
    truth, result, metrics = _run(tmp_path, SynthParams(**SIZE, relief=0.002), 7)
    assert result.parallax is not None and result.parallax.moved
    assert result.parallax.relief_px < 0.5
    note = result.relief_warning()
    assert note is not None and "back view" in note
    assert metrics.under_1 > 0.93  # 95.0 % at 768 px
    error = offset_error_px(truth, result.depth, truth.focal_px)
    assert abs(error) < 2 * result.ambiguity.offset_sigma_px
