"""Pilot test of the right position's parallax check in ``rigkit field`` (issue 37, item
7): a correct right frame of a nearly flat scene is accepted, as processing accepts it,
and an unmoved one is still refused, each with what it is."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import pytest

from rigkit.capture import create_session
from rigkit.capture.field import add_position_frame
from rigkit.capture.positioning import set_field_step
from rigkit.tui.app import FieldApp
from rigkit.tui.config import FieldConfig
from tests.capture.test_field import _tilted, similarity, texture
from tests.conftest import rig_file
from tests.tui.conftest import opened, synchronous
from tests.tui.test_flow import SIZE, take_position


@pytest.mark.parametrize(("moved", "expected"), [
    (True, "✔ parallax 1."),  # before: "✘ no parallax (0.37 px): the tripod was not moved"
    (False, "✘ no parallax: the disparities vary by"),
])
@synchronous
async def test_a_flat_scene_seen_from_beside_passes_and_an_unmoved_view_does_not(
        tmp_path: Path, moved: bool, expected: str) -> None:
    left = texture(480, 360, seed=5)
    right = _tilted(left, 1.6) if moved else similarity(left, 1.0, 0.4, (3.0, -2.0))
    session = create_session(tmp_path / "flat", rig_file(tmp_path, (480, 360)))
    for position, image in (("left", left), ("right", right)):
        path = tmp_path / f"{position}.png"
        cv2.imwrite(str(path), np.clip(np.rint(image), 0, 255).astype(np.uint8))
        session = add_position_frame(session, position, path)
    set_field_step(session.path, "right")
    app = FieldApp(FieldConfig(capture=tmp_path, session=session.path, graphics=False))
    async with app.run_test(size=SIZE) as pilot:
        await opened(pilot, app)
        checks = (await take_position(pilot, app, "right")).replace("\n", " ")
    assert expected in checks, checks
