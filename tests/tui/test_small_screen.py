"""Pilot tests of ``rigkit field`` at 60x20 (issue 37, item 6): every key in the key bar
on screen, the readings list shown, the depth scale with both ends and its unit."""

from __future__ import annotations

import re

from textual.widgets._footer import FooterKey

from rigkit.capture import LaserReading, add_target, utc_now
from rigkit.capture.positioning import set_field_step
from rigkit.synth.demo import Demo
from rigkit.tui.app import FieldApp
from rigkit.tui.config import FieldConfig
from rigkit.tui.screens import PositionScreen, ProcessScreen, TargetsScreen
from rigkit.tui.widgets import PixelView
from tests.tui.conftest import opened, synchronous, text, wait_for
from tests.tui.test_resume import framed

SMALL = (60, 20)


def shown_keys(app: FieldApp) -> set[str]:
    """The keys of the key bar drawn wholly inside the terminal."""
    width, height = app.size
    keys = app.screen.query(FooterKey)
    return {key.key for key in keys if key.region.width > 0
            and key.region.right <= width and key.region.bottom <= height}


async def keys_on_screen(pilot, app: FieldApp, keys: set[str]) -> None:
    """Wait for the key bar (drawn after its screen) to show ``keys``, all of them."""
    await wait_for(pilot, lambda: keys <= shown_keys(app),
                   f"{sorted(keys)} in the key bar, which shows {sorted(shown_keys(app))}", 5)


@synchronous
async def test_every_key_and_number_stays_on_a_60x20_screen(demo: Demo) -> None:
    session = framed(demo, "small", reading=False)
    add_target(session, "T1", (190.0, 140.0), readings=[
        LaserReading(r, utc_now(), "manual") for r in (200.4, 200.6)])
    set_field_step(session.path, "targets")
    app = FieldApp(FieldConfig(capture=demo.capture, session=session.path, graphics=False))
    async with app.run_test(size=SMALL) as pilot:
        await opened(pilot, app)
        await wait_for(pilot, lambda: isinstance(app.screen, TargetsScreen)
                       and app.screen.query_one(PixelView).cursor is not None, "the targets")
        await keys_on_screen(pilot, app, {"enter", "t", "m", "x", "n", "b", "q"})
        readings = app.screen.query_one("#readings")
        assert readings.region.height >= 2 and readings.region.bottom <= SMALL[1]
        assert "200.4" in text(app, "#readings") and "200.6" in text(app, "#readings")
        await pilot.press("b")
        await wait_for(pilot, lambda: isinstance(app.screen, PositionScreen), "the back step")
        await keys_on_screen(pilot, app, {"o", "x", "n", "b", "q"})
        await pilot.press("n")
        await wait_for(pilot, lambda: isinstance(app.screen, TargetsScreen), "the targets")
        await pilot.press("n")
        await wait_for(pilot, lambda: isinstance(app.screen, ProcessScreen), "processing")
        await wait_for(pilot, lambda: app.screen.query(".scale"), "the depth scale", 60)
        await keys_on_screen(pilot, app, {"r", "e", "n", "b", "q"})
        scale = app.screen.query_one(".scale")
        assert scale.region.right <= SMALL[0] and scale.region.bottom <= SMALL[1]
        bar = str(scale.render())
        assert "depth z, m" in bar and re.search(r"\d+ \S+ \d+", bar), bar  # both ends
