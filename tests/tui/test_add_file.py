"""Pilot test of ``o`` (add a file by its path) in ``rigkit field`` (issue 37, item 8):
what is refused at a glance is told at once and names the file; a later path never
shows an earlier one's word."""

from __future__ import annotations

import cv2
import numpy as np

from rigkit.synth.demo import Demo
from tests.tui.conftest import opened, side, synchronous, wait_for
from tests.tui.test_flow import SIZE, take_the_left_frame, watching_app


@synchronous
async def test_add_file_errors_name_the_path_just_given(demo: Demo) -> None:
    _, app = watching_app(demo)
    small = demo.root / "small.png"
    cv2.imwrite(str(small), np.zeros((10, 12), np.uint8))
    async with app.run_test(size=SIZE) as pilot:
        await opened(pilot, app)
        await take_the_left_frame(pilot, app, demo)  # a burst to compare with: slow checks
        await pilot.press("o", *str(demo.root / "nowhere.png"), "enter")
        await wait_for(pilot, lambda: "nowhere.png: no such file" in side(app),
                       "the missing file's error", 5)
        await pilot.press("o", *str(small), "enter")
        assert "nowhere.png" not in side(app)  # the old word is gone at once
        await wait_for(pilot, lambda: "small.png" in side(app)
                       and "12x10" in side(app), "the wrong size named", 5)
        assert "nowhere.png" not in side(app)
