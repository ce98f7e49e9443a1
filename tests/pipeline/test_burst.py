"""Bursts: frames of one position aligned and stacked, checked against the frame they
were made from."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from rigkit.errors import InputError
from rigkit.pipeline.burst import frame_shift, median, shifted, stack_burst, textured_crop
from rigkit.synth.shimmer import shimmer_field


def _texture(rng: np.random.Generator) -> np.ndarray:
    img = rng.uniform(0, 255, (300, 400)).astype(np.float32)
    return cv2.GaussianBlur(img, (0, 0), 1.5) * 2 - 100


def _moved(img: np.ndarray, dx: float, dy: float, rng, shimmer: float) -> np.ndarray:
    """``img`` seen again: shifted by (dx, dy), with shimmer and noise."""
    sx, sy = shimmer_field(img.shape, shimmer, 8.0, rng)
    v, u = np.mgrid[0 : img.shape[0], 0 : img.shape[1]].astype(np.float32)
    out = cv2.remap(img, u - dx + sx, v - dy + sy, cv2.INTER_CUBIC, borderMode=cv2.BORDER_REFLECT)
    return out + rng.normal(0, 2.0, img.shape).astype(np.float32)


def test_stacking_undoes_shifts_and_reduces_shimmer_and_noise() -> None:
    rng = np.random.default_rng(5)
    truth = _texture(rng)
    shifts = [(0, 0), (1.3, -0.4), (-2.2, 0.8), (0.6, 1.9), (-0.7, -1.1)]
    frames = [_moved(truth, dx, dy, rng, 0.3) for dx, dy in shifts]
    # Frame 1 is the reference grid: compare away from the borders.
    inner = (slice(20, -20), slice(20, -20))
    single = np.sqrt(np.mean((frames[0] - truth)[inner] ** 2))
    stacked = np.sqrt(np.mean((stack_burst(frames) - truth)[inner] ** 2))
    assert stacked < 0.7 * single


def test_one_frame_is_returned_as_it_is() -> None:
    img = _texture(np.random.default_rng(1))
    assert stack_burst([img]) is img


def test_frames_of_another_size_or_place_are_refused() -> None:
    img = _texture(np.random.default_rng(2))
    with pytest.raises(InputError, match="left burst: frame 2 is 400x299"):
        stack_burst([img, img[:-1]], "left burst")
    far = np.roll(img, 120, axis=1)
    with pytest.raises(InputError, match="frame 2 is shifted"):
        stack_burst([img, far], "left burst")


@pytest.mark.parametrize("n", [1, 2, 3, 4, 5, 8])
def test_median_is_numpys_and_keeps_the_frames(n: int) -> None:
    rng = np.random.default_rng(n)
    frames = [rng.normal(0, 50, (37, 53)).astype(np.float32) for _ in range(n)]
    frames[0][3, 4] = frames[-1][3, 4]  # ties
    kept = [f.copy() for f in frames]
    stacked = median(frames, rows=8)  # blocks that do not divide the height
    assert stacked.dtype == np.float32
    assert np.array_equal(stacked, np.median(np.stack(frames), axis=0).astype(np.float32))
    assert all(np.array_equal(f, k) for f, k in zip(frames, kept, strict=True))


def test_shift_is_measured_where_there_is_texture_not_on_a_plain_wall() -> None:
    # A plain wall fills the middle of the frame; the texture is at one side. The
    # central crop saw only noise there and found shifts of tens of px.
    rng = np.random.default_rng(7)
    img = np.full((1200, 1600), 90.0, np.float32)
    img[:, :250] = _texture(rng)[:, :250].repeat(4, axis=0)[:1200]
    frames = [img + rng.normal(0, 2.0, img.shape).astype(np.float32) for _ in range(2)]
    frames[1] = np.roll(frames[1], (1, 2), axis=(0, 1))
    rows, cols = textured_crop(img, 1024)
    assert cols.stop <= 1024 and cols.start == 0  # the textured side
    dx, dy = frame_shift(frames[0], frames[1])
    assert dx == pytest.approx(2.0, abs=0.2) and dy == pytest.approx(1.0, abs=0.2)


def test_shift_leaves_whole_frame_crops_unchanged() -> None:
    # A crop the size of the frame is a view of it: OpenCV's phase correlation must
    # not window the caller's frames in place.
    img = _texture(np.random.default_rng(8))
    kept = img.copy()
    frame_shift(img, img.copy())
    assert np.array_equal(img, kept)


@pytest.mark.parametrize(("dx", "dy"), [(0.0, 0.0), (0.37, -0.81), (-3.5, 12.25),
                                        (40.03125, -49.5), (1.0, -2.0)])
def test_shifted_is_opencvs_cubic_warp(dx: float, dy: float) -> None:
    """The separable shift is ``cv2.warpAffine``'s INTER_CUBIC translation with
    replicated edges, within 1e-4 of the image's range (OpenCV rounds the coordinates
    it samples at)."""
    img = _texture(np.random.default_rng(7))
    warp = np.array([[1.0, 0.0, -dx], [0.0, 1.0, -dy]])
    expected = cv2.warpAffine(img, warp, (img.shape[1], img.shape[0]), flags=cv2.INTER_CUBIC,
                              borderMode=cv2.BORDER_REPLICATE)
    span = float(img.max() - img.min())
    np.testing.assert_allclose(shifted(img, dx, dy), expected, rtol=0, atol=1e-4 * span)
