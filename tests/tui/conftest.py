"""Fixtures for the field TUI tests: the demo scene rendered once, copied per test, and
helpers to wait for the app and read what it shows."""

from __future__ import annotations

import asyncio
import functools
import shutil
import time
from collections.abc import Callable, Coroutine
from pathlib import Path
from typing import Any

import pytest

from rigkit.capture import create_session
from rigkit.synth.demo import Demo, prepare_demo

SHOT_S = 0.1  # the simulated camera and laser, fast
SETTLE_S = 0.2  # a new file counts after this long unchanged


@pytest.fixture(scope="session")
def demo_scene(tmp_path_factory: pytest.TempPathFactory) -> Demo:
    return prepare_demo(tmp_path_factory.mktemp("demo"), size=(384, 288), shot_s=SHOT_S)


@pytest.fixture
def demo(demo_scene: Demo, tmp_path: Path) -> Demo:
    """A private demo: the rendered scene and rig copied, an empty card folder and a new
    session (as `rigkit field --demo` starts)."""
    shutil.copytree(demo_scene.scene, tmp_path / "scene")
    shutil.copy(demo_scene.rig, tmp_path / "rig.yaml")
    copy = Demo(tmp_path, demo_scene.seed, SHOT_S, demo_scene.size, demo_scene.burst)
    copy.card.mkdir()
    copy.capture.mkdir()
    create_session(copy.session, copy.rig)
    return copy


def synchronous(test: Callable[..., Coroutine[Any, Any, None]]) -> Callable[..., None]:
    """Run an async pilot test in its own event loop (no asyncio plugin needed)."""

    @functools.wraps(test)
    def run(*args: Any, **kwargs: Any) -> None:
        asyncio.run(test(*args, **kwargs))

    return run


async def wait_for(pilot, condition: Callable[[], bool], what: str, timeout: float = 20.0
                   ) -> None:
    """Let the app run until ``condition()`` holds; fail naming ``what`` after ``timeout``."""
    deadline = time.monotonic() + timeout
    while not condition():
        if time.monotonic() > deadline:
            pytest.fail(f"timed out waiting for {what}; the screen shows: {shown(pilot.app)}")
        await pilot.pause(0.05)


async def opened(pilot, app) -> None:
    """Wait for the app's first step (or start) screen: its first screen says what it
    opens while the steps' libraries load, and keys pressed there go nowhere."""
    from rigkit.tui.app import OpeningScreen

    await wait_for(pilot, lambda: not isinstance(app.screen, OpeningScreen)
                   and app.screen.is_mounted, "the first step")


def shown(app) -> str:
    """What the current screen's text widgets show, one line (for a failure message)."""
    from textual.widgets import Static

    texts = (str(widget.render()).strip() for widget in app.screen.query(Static))
    return " | ".join(t.replace("\n", " ") for t in texts if t)[:3000]


def text(app, selector: str) -> str:
    """The plain text a Static on the current screen shows."""
    return str(app.screen.query_one(selector).render())


def side(app) -> str:
    """What a position's side panel says of its frames: the question held, the newest
    frame's state and its checks."""
    parts = ("#question", "#status", "#checks")
    return "\n".join(str(w.render()) for s in parts for w in app.screen.query(s))


def write_frame(path: Path, image_path: Path, iso: int | None = None) -> Path:
    """Copy a rendered frame to ``path`` as PNG, with EXIF saying ISO ``iso`` if given."""
    from PIL import Image

    exif = Image.Exif()
    if iso is not None:
        exif[0x0110] = "synthetic pinhole"
        exif.get_ifd(0x8769)[0x8827] = iso
    tmp = path.with_name("." + path.name)  # hidden while written: not picked up early
    Image.open(image_path).save(tmp, format="PNG", exif=exif)
    tmp.rename(path)
    return path
