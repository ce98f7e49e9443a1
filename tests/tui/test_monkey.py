"""A seeded "monkey" drive of ``rigkit field`` (issue 49): a few hundred random keys and
terminal sizes on every step while frames land on the card and the laser fires, and then
what must hold whatever was pressed: no crash, every frame filed at the position on show
when it landed (the keys that file a frame elsewhere, ``a``, ``f``, ``c`` and ``o``, are
not among the monkey's), every shot the laser sent in the session or its history, and a
``session.yaml`` that loads."""

from __future__ import annotations

import random
from pathlib import Path

import pytest

from rigkit.capture import add_target, load_session
from rigkit.capture.positioning import set_field_step
from rigkit.synth.demo import Demo
from rigkit.tui.app import Arrival, FieldApp, LinkNews
from rigkit.tui.config import FieldConfig
from rigkit.tui.messages import Goto
from tests.tui.conftest import SETTLE_S, opened, synchronous, wait_for, write_frame
from tests.tui.test_operator import other_scene
from tests.tui.test_resume import framed

SEED = 49
PRESSES = 200
KEYS = ("n", "b", "n", "b", "n", "b", "x", "t", "m", "d", "left_square_bracket",
        "right_square_bracket", "enter", "escape", "up", "down", "left", "right", "shift+left",
        "shift+up", "plus", "minus", "r", "e", "pagedown", "2", "0", "1", ".", "5", "ctrl+l",
        "space")
SCHEDULE = ("rig", "left", "right", "back", "targets", "process", "targets", "left", "back")
SIZES = ((80, 24), (60, 20), (100, 32), (72, 22), (120, 40))


@pytest.mark.slow
@synchronous
async def test_random_keys_and_sizes_lose_nothing_and_file_nothing_elsewhere(
        demo: Demo, monkeypatch) -> None:
    session = framed(demo, "monkey", reading=False)
    add_target(session, "T1", (190.0, 140.0))
    set_field_step(session.path, "rig")
    arrived: dict[Path, str | None] = {}  # each frame, and the position on show on arrival
    sent: list[float] = []  # every range the laser sent

    on_arrival, on_link_news = FieldApp.on_arrival, FieldApp.on_link_news

    def arrival(app: FieldApp, message: Arrival) -> None:
        arrived[message.path] = app.current_position()
        on_arrival(app, message)

    def news(app: FieldApp, message: LinkNews) -> None:
        if not hasattr(message.news, "message"):  # a reading, not the link's state
            sent.append(message.news.slope_distance_m)  # type: ignore[union-attr]
        on_link_news(app, message)

    monkeypatch.setattr(FieldApp, "on_arrival", arrival)
    monkeypatch.setattr(FieldApp, "on_link_news", news)
    app = FieldApp(FieldConfig(capture=demo.capture, session=session.path, watch=demo.card,
                               port="sim://trupulse?interval=1&distance=200.5&noise=0.05",
                               graphics=False, settle_s=SETTLE_S))
    rng = random.Random(SEED)
    visited: set[str | None] = set()
    async with app.run_test(size=(80, 24)) as pilot:
        await opened(pilot, app)
        await wait_for(pilot, lambda: app.step == "rig", "the rig step")
        press = 0
        for step in SCHEDULE:  # each step gets its share of keys (which may leave it)
            app.post_message(Goto(step))
            await wait_for(pilot, lambda s=step: app.step == s and app.screen.is_mounted, step)
            for _ in range(PRESSES // len(SCHEDULE)):
                press += 1
                if press % 25 == 0:
                    await pilot.resize_terminal(*rng.choice(SIZES))
                position = app.current_position()
                if press % 8 == 0 and position is not None:
                    name = demo.card / f"DSCN{press:04d}.PNG"
                    if rng.random() < 0.2:  # another scene: held with a question
                        other_scene(name, demo.scene / "left.png")
                    else:  # the position's view, a new file each time (its ISO differs)
                        write_frame(name, demo.scene / f"{position}.png", iso=100 + press)
                await pilot.press(rng.choice(KEYS))
                visited.add(app.step)
        await pilot.press("escape")
        await pilot.pause(1.0)
        assert app.is_running and app._exception is None
        await pilot.press("q", "q")  # asked first while shots are held
    assert app._exception is None
    saved = load_session(session.path)  # a valid session.yaml
    for position in ("left", "right", "back"):
        for frame in saved.bursts.get(position, ()):
            card = demo.card / Path(frame.file).name
            if card in arrived:
                assert arrived[card] == position, f"{card.name} filed at {position}"
    history = (session.path / "history.log").read_text()
    kept = [r.slope_distance_m for t in saved.targets for r in t.readings]
    lost = [r for r in sent if r not in kept and f"{r:.2f} m" not in history]
    assert sent and not lost
    assert any(arrived.values())  # frames did land on the positions
    assert visited >= {"rig", "left", "right", "back", "targets", "process"}, visited
