"""Preview images: colour maps, and the laser targets drawn on them."""

from __future__ import annotations

import math

import numpy as np

from rigkit.capture.model import LaserReading, Target
from rigkit.reporting.previews import (
    PREVIEW_WIDTH,
    _text,
    colorize,
    mark_targets,
    preview_set,
)
from tests.conftest import make_row

GREY = 90


def _target(name: str, u: float, v: float, window: int = 41) -> Target:
    return Target(name, (u, v), window, (LaserReading(300.0, "t", "manual"),))


def _changed(before: np.ndarray, after: np.ndarray) -> np.ndarray:
    return np.any(before != after, axis=2)


def test_targets_are_boxed_at_their_scaled_pixel_and_labelled() -> None:
    img = np.full((600, 800, 3), GREY, np.uint8)  # a 1600 x 1200 image shrunk by half
    out = mark_targets(img, (1200, 1600), [_target("T1", 400.0, 300.0)], [])
    assert out.shape == img.shape and (img == GREY).all()  # a copy; the input is kept
    changed = _changed(img, out)
    # The window, 41 px at full size, is a box 2 x 10 px across around (200, 150).
    for x, y in ((190, 150), (210, 150), (200, 140), (200, 160)):
        assert changed[y, x], (x, y)
    assert not changed[150, 200] and not changed[145:156, 195:206].any()  # outline only
    assert changed[130:170, 216:260].any()  # the label, right of the box
    assert not changed[:, :180].any()  # nothing left of it
    assert not changed[:100].any() and not changed[200:].any()


def test_a_label_near_the_right_edge_goes_left_of_the_box() -> None:
    img = np.full((600, 800, 3), GREY, np.uint8)
    out = mark_targets(img, (600, 800), [_target("T9", 780.0, 300.0, 9)],
                       [make_row("T9", 300.0, 0.5)])
    changed = _changed(img, out)
    assert changed[280:320, 600:770].any()  # the label, left of the target
    assert changed[300, 774] and changed[300, 786]  # the box around (780, 300)
    assert not changed[:, 790:].any()  # nothing right of the box


def test_label_text_says_laser_estimate_and_error() -> None:
    target = _target("T1", 10.0, 10.0)
    assert _text(target, None) == "T1"
    assert _text(target, make_row("T1", 300.0, 0.5)) == "T1  laser 300.0 m  est 301.5 m  +0.50 %"
    missing = make_row("T1", 300.0, 0.0, status="no_estimate")
    assert math.isnan(missing.estimate_range_m)
    assert _text(target, missing) == "T1  laser 300.0 m  no estimate"


def test_the_preview_set_marks_targets_on_depth_and_left() -> None:
    h, w = 900, 2400  # wider than PREVIEW_WIDTH: shrunk
    left = np.full((h, w), 120.0, np.float32)
    depth = np.full((h, w), 300.0, np.float32)
    depth[:, : w // 3] = np.nan
    sigma = np.full((h, w), 1.5, np.float32)
    target = _target("T1", 1800.0, 450.0)
    marked = preview_set(left, depth, sigma, [target], [make_row("T1", 300.0, 0.2)])
    plain = preview_set(left, depth, sigma, [], [])
    assert set(marked) == {"depth.png", "sigma.png", "left.png"}
    scale = PREVIEW_WIDTH / w
    assert marked["left.png"].shape == (round(h * scale), PREVIEW_WIDTH, 3)
    for name in ("depth.png", "left.png"):
        changed = _changed(plain[name], marked[name])
        u, v, half = round(1800 * scale), round(450 * scale), max(6, round(41 * scale / 2))
        assert changed[v, u - half] and changed[v, u + half] and changed[v - half, u]
        assert not changed[v, u]  # the box is an outline
        assert not changed[: v - 40].any() and not changed[v + 40 :].any()
    assert np.array_equal(marked["sigma.png"], plain["sigma.png"])  # sigma is not marked
    assert np.array_equal(marked["depth.png"][:, :100], colorize(depth, 300.0, 300.0,
                                                                 "depth z (m)")[:, :100])
