"""The stereo disparity: sub-pixel accuracy (rigkit.pipeline.stereo.SGBM), the
footprint check (rigkit.pipeline.stereo.restrict_to_footprints) and hole filling
(rigkit.pipeline.stereo.fill_holes)."""

from __future__ import annotations

import numpy as np

from rigkit.pipeline.stereo import SGBM, fill_holes, restrict_to_footprints
from tests.pipeline.textures import plane_waves

NAN = np.nan


def _row(*values: float) -> np.ndarray:
    return np.array([values], np.float32)


def test_a_narrow_gap_takes_the_farther_neighbour() -> None:
    # Foreground (disparity 30) left of the gap, background (20) right of it: the occluded
    # pixels belong to the background, the smaller disparity.
    disp = _row(30, 30, NAN, NAN, NAN, 20, 20)
    filled, mask = fill_holes(disp, max_gap=3)
    assert filled.tolist() == [[30, 30, 20, 20, 20, 20, 20]]
    assert mask.tolist() == [[False, False, True, True, True, False, False]]
    # The same with the background on the left.
    filled, _ = fill_holes(_row(12.5, NAN, 40), max_gap=3)
    assert filled.tolist() == [[12.5, 12.5, 40]]


def test_wider_gaps_stay_empty() -> None:
    disp = _row(30, NAN, NAN, NAN, NAN, 20)
    filled, mask = fill_holes(disp, max_gap=3)
    assert np.isnan(filled[0, 1:5]).all() and not mask.any()
    assert fill_holes(disp, max_gap=4)[1].sum() == 4  # exactly max_gap is filled


def test_gaps_touching_the_border_stay_empty() -> None:
    disp = _row(NAN, NAN, 25, 25, NAN)
    filled, mask = fill_holes(disp, max_gap=5)
    assert np.isnan(filled[0, [0, 1, 4]]).all() and not mask.any()
    assert np.isnan(fill_holes(_row(NAN, NAN, NAN), max_gap=5)[0]).all()  # nothing valid


def test_rows_are_independent_and_the_input_is_kept() -> None:
    disp = np.array([[10, NAN, 10], [NAN, 7, 7], [5, NAN, 9]], np.float32)
    before = disp.copy()
    filled, mask = fill_holes(disp, max_gap=1)
    assert np.array_equal(filled, np.array([[10, 10, 10], [NAN, 7, 7], [5, 5, 9]], np.float32),
                          equal_nan=True)
    assert mask.tolist() == [[False, True, False], [False, False, False], [False, True, False]]
    assert np.array_equal(disp, before, equal_nan=True)
    assert filled.dtype == np.float32


def test_disparities_are_not_drawn_to_whole_pixels() -> None:
    # Pairs with a known constant disparity, a quarter and three quarters of a pixel off
    # a whole one; one pass of semi-global matching alone gave -0.125 and +0.19 px.
    left = (128 + 30 * plane_waves((0, 0), (256, 320))).astype(np.float32)
    core = (slice(20, -20), slice(40, -20))
    for true in (5.25, 5.75):
        right = (128 + 30 * plane_waves((true, 0), (256, 320))).astype(np.float32)
        error = SGBM()(left, right, (0, 16))[core] - true
        assert np.isfinite(error).mean() > 0.99
        assert abs(np.nanmedian(error)) < 0.05
        assert np.nanpercentile(np.abs(error), 90) < 0.1


def test_a_match_outside_the_right_footprint_is_dropped() -> None:
    # Left columns 0..5 with their disparities; the right image shows columns 2..5 only.
    # Matches land at x - d: 3 (seen), 2.5 (halves go to the even column 2: seen),
    # 1.5 (to 2: seen), 1 (unseen), -1 (off the image), and an unknown disparity.
    disp = _row(-3, -1.5, 0.5, 2, 5, NAN)
    right_valid = np.array([[False, False, True, True, True, True]])
    left_valid = np.ones_like(right_valid)
    left_valid[0, 0] = False  # and a left pixel outside its own footprint
    out = restrict_to_footprints(disp, left_valid, right_valid)
    np.testing.assert_array_equal(out, _row(NAN, -1.5, 0.5, NAN, NAN, NAN))
