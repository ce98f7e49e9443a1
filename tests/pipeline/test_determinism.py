"""The same depth, bit for bit, whatever the number of BLAS and OpenCV threads
(rigkit.core.threads; issue 34). A field scene with a lens is the case that showed it:
its lens fit's least squares, split across BLAS threads, used to move a few pixels'
depth by metres."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import cv2
import numpy as np
import pytest
from threadpoolctl import threadpool_info, threadpool_limits

from rigkit.imagefile.decode import load_grey
from rigkit.pipeline import DepthResult, RigGeometry, estimate_depth
from rigkit.synth import SynthParams, generate_scene, load_scene, write_scene
from rigkit.synth.scene import field_params

LENS = (0.47, 0.0, 0.0, 0.0, 0.0)


@pytest.fixture(scope="module")
def field_lens_scene(tmp_path_factory: pytest.TempPathFactory) -> Path:
    params = replace(field_params(SynthParams(width=480, height=360)), distortion=LENS)
    out = tmp_path_factory.mktemp("determinism") / "field-lens"
    write_scene(generate_scene(params, seed=3), out)
    return out


def _depth(scene: Path, blas: int, opencv: int) -> DepthResult:
    truth = load_scene(scene)
    views = [load_grey(truth.image_path(v)) for v in ("left", "right", "back")]
    rig = RigGeometry(truth.focal_px, truth.baseline_lr_m, truth.baseline_lb_m, LENS)
    before = cv2.getNumThreads()
    cv2.setNumThreads(opencv)
    try:
        with threadpool_limits(limits=blas, user_api="blas"):
            return estimate_depth(*views, rig)
    finally:
        cv2.setNumThreads(before)


def test_depth_is_the_same_on_one_blas_thread_or_two(field_lens_scene: Path) -> None:
    one, two = _depth(field_lens_scene, 1, 1), _depth(field_lens_scene, 2, 2)
    assert np.isfinite(one.depth).mean() > 0.5  # a real result, not two empty ones
    np.testing.assert_array_equal(one.depth, two.depth)
    np.testing.assert_array_equal(one.sigma, two.sigma)
    assert one.ambiguity.offset_px == two.ambiguity.offset_px
    assert one.lens_fit is not None and two.lens_fit is not None
    assert one.lens_fit.as_dict() == two.lens_fit.as_dict()


def test_the_callers_blas_threads_come_back_after_a_run(field_lens_scene: Path) -> None:
    with threadpool_limits(limits=2, user_api="blas"):
        _depth(field_lens_scene, 2, 1)
        assert {i["num_threads"] for i in threadpool_info() if i["user_api"] == "blas"} == {2}
