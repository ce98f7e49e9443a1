"""The same depth, bit for bit, whatever the number of BLAS and OpenCV threads
(rigkit.core.threads; issue 34). A field scene with a lens is the case that showed it:
its lens fit's least squares, split across BLAS threads, used to move a few pixels'
depth by metres. The work split into pieces of a fixed layout (issue 52: semi-global
matching's bands, the views' comparisons, the depth map's chunks) is checked on 1, 2
and 16 threads."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import cv2
import numpy as np
import pytest
from threadpoolctl import threadpool_info, threadpool_limits

from rigkit.imagefile.decode import load_grey
from rigkit.pipeline import DepthResult, RigGeometry, estimate_depth, stereo
from rigkit.pipeline.agreement import shimmer_steps
from rigkit.synth import SynthParams, generate_scene, load_scene, write_scene
from rigkit.synth.scene import field_params
from tests.pipeline.textures import plane_waves

LENS = (0.47, 0.0, 0.0, 0.0, 0.0)


@pytest.fixture(scope="module")
def field_lens_scene(tmp_path_factory: pytest.TempPathFactory) -> Path:
    params = replace(field_params(SynthParams(width=480, height=360)), distortion=LENS)
    out = tmp_path_factory.mktemp("determinism") / "field-lens"
    write_scene(generate_scene(params, seed=3), out)
    return out


@pytest.fixture(scope="module")
def shimmer_scene(tmp_path_factory: pytest.TempPathFactory) -> Path:
    # Midday air and movers: the views' agreement compares each window at 3 and 9 offsets.
    params = replace(field_params(SynthParams(width=576, height=432)), shimmer_px=1.0,
                     n_movers=3)
    out = tmp_path_factory.mktemp("determinism") / "shimmer"
    write_scene(generate_scene(params, seed=9), out)
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


def test_every_piece_of_a_run_is_the_same_on_one_two_or_sixteen_threads(
        shimmer_scene: Path) -> None:
    # The pieces of a fixed layout (the depth map's row chunks, the hole filling's bands,
    # the back view's positions, each view's comparison at each offset) spread over as
    # many threads as OpenCV has.
    runs = [_depth(shimmer_scene, 1, threads) for threads in (1, 2, 16)]
    a = runs[0].ambiguity
    steps = (shimmer_steps(runs[0].rectification.row_rms_px, runs[0].disparity_scale, 1),
             shimmer_steps(a.rms_px / np.sqrt(2), runs[0].disparity_scale, 2))
    assert [len(s) for s in steps] == [3, 9]
    assert runs[0].disagree.any() and np.isfinite(runs[0].depth).mean() > 0.3
    for other in runs[1:]:
        for name in ("depth", "sigma", "disparity", "disagree", "filled", "no_surface"):
            np.testing.assert_array_equal(getattr(runs[0], name), getattr(other, name))
        b = other.ambiguity
        assert (b.offset_px, b.offset_sigma_px, b.rms_px) == (a.offset_px, a.offset_sigma_px,
                                                              a.rms_px)


def test_the_callers_blas_threads_come_back_after_a_run(field_lens_scene: Path) -> None:
    with threadpool_limits(limits=2, user_api="blas"):
        _depth(field_lens_scene, 2, 1)
        assert {i["num_threads"] for i in threadpool_info() if i["user_api"] == "blas"} == {2}


def test_the_stereo_bands_give_the_same_disparities_on_any_number_of_threads(
        monkeypatch: pytest.MonkeyPatch) -> None:
    # A pair of known disparity (5.25 px) cut into 5 bands of 80 rows: every thread count
    # gives the same disparities, and the rows at the seams are as good as the others.
    monkeypatch.setattr(stereo, "BAND_ROWS", 80)
    size, true = (420, 192), 5.25
    left = (128 + 30 * plane_waves((0, 0), size)).astype(np.float32)
    right = (128 + 30 * plane_waves((true, 0), size)).astype(np.float32)
    assert len(stereo.bands(size[0])) == 5
    before = cv2.getNumThreads()
    found = []
    try:
        for threads in (1, 2, 16):
            cv2.setNumThreads(threads)
            found.append(stereo.SGBM()(left, right, (0, 16)))
    finally:
        cv2.setNumThreads(before)
    for other in found[1:]:
        np.testing.assert_array_equal(found[0], other)
    error = np.abs(found[0][:, 40:-20] - true)
    seams = np.zeros(size[0], bool)
    for r0, _ in stereo.bands(size[0])[1:]:
        seams[r0 - 4:r0 + 4] = True
    for rows in (seams, ~seams):
        assert np.isfinite(error[rows]).mean() > 0.99
        assert np.nanpercentile(error[rows], 90) < 0.1
