"""Heat shimmer measured from two frames: frames warped by the renderer's own shimmer
fields of known strength and correlation length, with a tripod's sway between them."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from rigkit.errors import PipelineError
from rigkit.pipeline.shimmer import burst_shimmer, measure_shimmer
from rigkit.synth.shimmer import shimmer_field

SIZE = (1024, 1280)  # (H, W)
CORR_PX = 24.0


def _texture(seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    noise = cv2.GaussianBlur(rng.random(SIZE).astype(np.float32), (0, 0), 1.5)
    return cv2.normalize(noise, None, 30, 220, cv2.NORM_MINMAX)


def _frame(scene: np.ndarray, rms_px: float, rng: np.random.Generator,
           sway: tuple[float, float, float] = (0.0, 0.0, 0.0)) -> np.ndarray:
    """``scene`` seen through fresh shimmer, moved by ``sway`` (dx, dy px, roll deg)
    and with 1 DN of sensor noise."""
    h, w = scene.shape
    v, u = np.mgrid[0:h, 0:w].astype(np.float32)
    if rms_px > 0:
        dx, dy = shimmer_field(scene.shape, rms_px, CORR_PX, rng)
        u, v = u + dx, v + dy
    seen = cv2.remap(scene, u, v, cv2.INTER_CUBIC, borderMode=cv2.BORDER_REFLECT)
    m = cv2.getRotationMatrix2D((w / 2, h / 2), sway[2], 1.0)
    m[:, 2] += sway[:2]
    moved = cv2.warpAffine(seen, m, (w, h), flags=cv2.INTER_CUBIC,
                           borderMode=cv2.BORDER_REFLECT)
    return moved + rng.normal(0, 1.0, scene.shape).astype(np.float32)


@pytest.mark.parametrize("rms_px", [0.15, 0.3, 0.6])
def test_recovers_the_shimmer_of_each_frame(rms_px: float) -> None:
    rng = np.random.default_rng(int(rms_px * 100))
    scene = _texture(1)
    first = _frame(scene, rms_px, rng)
    other = _frame(scene, rms_px, rng, sway=(3.4, -1.7, 0.05))  # the tripod swayed
    shimmer = measure_shimmer(first, other)
    assert shimmer.rms_px == pytest.approx(rms_px, rel=0.2)
    assert shimmer.corr_px == pytest.approx(CORR_PX, rel=0.25)
    assert shimmer.tracker_px < 0.5 * rms_px  # what the fit put down to the tracker
    assert shimmer.points > 1000


def test_still_air_measures_no_shimmer() -> None:
    rng = np.random.default_rng(5)
    scene = _texture(2)
    shimmer = measure_shimmer(_frame(scene, 0.0, rng), _frame(scene, 0.0, rng, (1.2, 0.4, 0)))
    assert shimmer.rms_px < 0.03
    assert np.isnan(shimmer.corr_px)


def test_a_blank_frame_has_nothing_to_measure() -> None:
    blank = np.full(SIZE, 120.0, np.float32)
    with pytest.raises(PipelineError, match="left burst: too little texture"):
        measure_shimmer(blank, blank, "left burst")


def test_frames_of_different_views_are_refused() -> None:
    with pytest.raises(PipelineError, match="same view"):
        measure_shimmer(_texture(3), _texture(4))


def test_a_burst_is_measured_on_its_first_two_frames() -> None:
    rng = np.random.default_rng(6)
    scene = _texture(5)
    frames = [_frame(scene, 0.3, rng) for _ in range(3)]
    found = burst_shimmer(frames, "back")
    assert found is not None and found[1] == "back frames 1 and 2"
    assert found[0] == measure_shimmer(frames[0], frames[1])
    assert burst_shimmer(frames[:1], "back") is None  # one frame: nothing to compare
    assert burst_shimmer([_texture(3), _texture(4)], "back") is None  # not measurable
