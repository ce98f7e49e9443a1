"""Save the SVG screenshots of docs/field.md: the demo flow at 80x24, and a right frame
that is the left one again. Run from the checkout: .venv/bin/python scripts/field_screenshots.py
"""

from __future__ import annotations

import asyncio
import shutil
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

import cv2

from rigkit.capture import create_session
from rigkit.synth.demo import prepare_demo
from rigkit.tui.app import FieldApp
from rigkit.tui.config import FieldConfig
from rigkit.tui.screens import PositionScreen
from rigkit.tui.widgets import PixelView

OUT = Path(__file__).resolve().parents[1] / "docs" / "field"


async def until(pilot, condition: Callable[[], bool], timeout: float = 60.0) -> None:
    deadline = time.monotonic() + timeout
    while not condition():
        if time.monotonic() > deadline:
            shown = " | ".join(str(w.render()) for w in pilot.app.screen.query("Static"))
            raise TimeoutError(f"the demo did not get there; the screen shows: {shown}")
        await pilot.pause(0.1)


def checked(app: FieldApp, position: str, frames: int = 1) -> bool:
    """Whether ``position``'s screen shows the checks of its ``frames``-th frame."""
    screen = app.screen
    of = f" of {frames}" if frames > 1 else ""
    return (isinstance(screen, PositionScreen) and screen.position == position
            and f"({position} frame {frames}{of})" in str(screen.query_one("#status").render()))


async def shoot(pilot, app: FieldApp, name: str) -> None:
    await pilot.pause(0.5)  # let the preview mount
    app.save_screenshot(name, str(OUT))


async def flow(root: Path) -> None:
    demo = prepare_demo(root, shot_s=0.2)
    demo.prepare()  # the session, and where its tripod stood
    app = FieldApp(FieldConfig(capture=demo.capture, session=demo.session, demo=demo,
                               graphics=False))
    async with app.run_test(size=(80, 24)) as pilot:
        await pilot.pause(0.5)
        await shoot(pilot, app, "rig.svg")
        for position in ("left", "right", "back"):
            await pilot.press("n")
            await until(pilot, lambda p=position: checked(app, p, demo.burst))
            await shoot(pilot, app, f"{position}.svg")
        await pilot.press("n")
        await until(pilot, lambda: app.screen.query(PixelView)
                    and app.screen.query_one(PixelView).cursor is not None)
        for moves in (["shift+left", "left", "left", "left", "left", "shift+up"],  # spread out:
                      ["shift+right"] * 2 + ["right"] * 8 + ["shift+down"] * 2):  # on the map
            await pilot.press(*moves, "enter")
            count = len(app.session.targets)
            await until(pilot, lambda c=count: len(app.session.targets[c - 1].readings) >= 3)
        await pilot.press("right", "right", "plus")
        await shoot(pilot, app, "targets.svg")
        await pilot.press("n")
        await until(pilot, lambda: "targets within" in str(app.screen.query_one("#verdict")
                                                           .render()))
        await shoot(pilot, app, "process.svg")
        await pilot.press("q")


async def same_frame_twice(root: Path) -> None:
    """The right position given the left view again: another exposure (one grey level
    brighter, so not the same file, which is refused as such) from the unmoved camera."""
    demo = prepare_demo(root / "again", shot_s=0.2)
    session = create_session(demo.capture / "mistake", demo.rig).path
    app = FieldApp(FieldConfig(capture=demo.capture, session=session, watch=demo.card,
                               graphics=False))
    async with app.run_test(size=(80, 24)) as pilot:
        await pilot.press("n")
        await until(pilot, lambda: isinstance(app.screen, PositionScreen))
        shutil.copy(demo.scene / "left.png", demo.card / "DSCN0001.PNG")
        await until(pilot, lambda: checked(app, "left"))
        await pilot.press("n")
        await until(pilot, lambda: isinstance(app.screen, PositionScreen)
                    and app.screen.position == "right")
        again = cv2.imread(str(demo.scene / "left.png"), cv2.IMREAD_UNCHANGED)
        cv2.imwrite(str(demo.card / "DSCN0002.PNG"), cv2.add(again, 1))
        await until(pilot, lambda: checked(app, "right"))
        await shoot(pilot, app, "same-frame.svg")
        await pilot.press("q")


def main() -> None:
    OUT.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory() as tmp:
        asyncio.run(flow(Path(tmp)))
        asyncio.run(same_frame_twice(Path(tmp)))
    print(f"wrote {', '.join(sorted(p.name for p in OUT.glob('*.svg')))} in {OUT}")


if __name__ == "__main__":
    main()
