"""Pilot tests of ``rigkit field`` for the operator's hour, second pass (issue 49): one
or more per item of the issue, each written against what 81dfff3 did wrong."""

from __future__ import annotations

import re
import shutil
import subprocess
import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
import yaml
from textual.widgets._footer import FooterKey

from rigkit.batch import new_run_id, process_session
from rigkit.capture import LaserReading, Target, add_target, create_session, load_session
from rigkit.capture.field import add_position_frame, frames_at
from rigkit.capture.positioning import set_field_step
from rigkit.capture.session import save_session
from rigkit.errors import InputError
from rigkit.rangefinder.follow import LinkStatus, quiet_note
from rigkit.synth.demo import Demo
from rigkit.tui.app import FieldApp
from rigkit.tui.config import FieldConfig
from rigkit.tui.screens import PositionScreen, ProcessScreen, RigScreen, TargetsScreen
from rigkit.tui.widgets import PixelView
from tests.tui.conftest import SETTLE_S, opened, side, synchronous, text, wait_for, write_frame
from tests.tui.test_flow import SIZE, take_position, take_the_left_frame, watching_app
from tests.tui.test_resume import READING, app_at, app_on, framed


def readings_of(session: Path) -> dict[str, list[float]]:
    return {t.name: [r.slope_distance_m for r in t.readings]
            for t in load_session(session).targets}


def laser(app: FieldApp) -> str:
    """What the screen on show says of the laser ("" where it says nothing)."""
    return " ".join(str(w.render()) for s in ("LaserLine", "#link") for w in app.screen.query(s))


def key_bar(app: FieldApp) -> set[str]:
    """The keys the key bar shows, wholly inside the terminal."""
    width, height = app.size
    return {key.key for key in app.screen.query(FooterKey) if key.region.width > 0
            and key.region.right <= width and key.region.bottom <= height}


def other_scene(path: Path, like: Path) -> Path:
    """A frame the size of ``like`` that shows another scene (a smooth random texture)."""
    from PIL import Image

    width, height = Image.open(like).size
    rng = np.random.default_rng(5)
    coarse = rng.uniform(0, 255, (height // 8 + 1, width // 8 + 1))
    image = np.kron(coarse, np.ones((8, 8)))[:height, :width]
    hidden = path.with_name("." + path.name)
    Image.fromarray(image.astype(np.uint8)).save(hidden, format="PNG")
    hidden.rename(path)
    return path


# -- 1. fast keys -------------------------------------------------------------------------


@synchronous
async def test_fast_keys_never_crash_and_the_step_shown_is_the_one_resumed(demo: Demo,
                                                                          monkeypatch) -> None:
    """Before: ``nbnbnb`` ended the app with NoMatches (a worker updating the targets or
    process screen after it was replaced), processing started on every pass through its
    step, and the next start resumed at an older step than the one shown."""
    import rigkit.tui.screens.process as process

    runs: list[Path] = []

    def counted(path: Path, *args, **kwargs):
        runs.append(path)
        raise InputError(f"{path}: not run in this test")

    monkeypatch.setattr(process, "process_session", counted)
    session, app = app_at(demo, "fast", "back")
    async with app.run_test(size=SIZE) as pilot:
        await opened(pilot, app)
        await wait_for(pilot, lambda: isinstance(app.screen, PositionScreen), "the back step")
        for _ in range(12):
            await pilot.press("n", "n", "b", "n", "b", "b")
        await pilot.press("n")
        await pilot.pause(1.0)
        assert isinstance(app.screen, TargetsScreen) and app._exception is None
        assert len(runs) < 6  # passing through the process step starts nothing (24 runs)
        await pilot.press("q")
    assert app._exception is None
    assert load_session(session.path).field_step == "targets"


@synchronous
async def test_quit_just_after_a_step_opened_resumes_at_that_step(demo: Demo,
                                                                  monkeypatch) -> None:
    """Before: the step was recorded by a worker the app did not wait for, so a quit
    pressed while ``session.yaml`` was being written resumed at the step before (CI saw
    it once in 1664 tests; slow writes here make it happen every time)."""
    import rigkit.capture.positioning as positioning

    write = positioning.set_field_step

    def slow(path: Path, step: str):
        time.sleep(0.3)
        return write(path, step)

    session = framed(demo, "quick-quit")
    set_field_step(session.path, "left")
    monkeypatch.setattr(positioning, "set_field_step", slow)
    app = app_on(demo, session.path)
    async with app.run_test(size=SIZE) as pilot:
        await opened(pilot, app)
        await wait_for(pilot, lambda: isinstance(app.screen, PositionScreen)
                       and app.screen.position == "left", "the left step")
        await pilot.press("n")
        await wait_for(pilot, lambda: isinstance(app.screen, PositionScreen)
                       and app.screen.position == "right", "the right step")
        await pilot.press("q")
    assert app._exception is None
    assert load_session(session.path).field_step == "right"


@synchronous
async def test_a_position_visited_again_shows_its_checks_without_checking_again(
        demo: Demo, monkeypatch) -> None:
    """Before: every visit of a position ran its checks again in another thread, and
    the keys queued behind them."""
    import rigkit.capture.field as field
    import rigkit.tui.app

    calls: list[str] = []
    checks = field.onsite_checks

    def counted(session, position):
        calls.append(position)
        return checks(session, position)

    monkeypatch.setattr(field, "onsite_checks", counted)
    monkeypatch.setattr(rigkit.tui.app, "onsite_checks", counted, raising=False)  # 81dfff3's
    session, app = app_at(demo, "visits", "left", reading=False)
    async with app.run_test(size=SIZE) as pilot:
        await opened(pilot, app)
        await take_position(pilot, app, "left")
        for _ in range(4):
            await pilot.press("n")
            await take_position(pilot, app, "right")
            await pilot.press("b")
            await take_position(pilot, app, "left")
    assert calls.count("left") <= 2 and calls.count("right") <= 2  # newest_failed's too


# -- 2. the laser belongs to the app --------------------------------------------------------


@synchronous
async def test_shots_fired_on_any_screen_are_kept(demo: Demo) -> None:
    """Before: the port was open only on the targets step; a shot fired on another step
    was dropped without a word."""
    session = framed(demo, "shots", reading=False)
    add_target(session, "T1", (190.0, 140.0))
    set_field_step(session.path, "rig")
    port = "sim://trupulse?interval=0.1&distance=201.5"
    app = FieldApp(FieldConfig(capture=demo.capture, session=session.path, port=port,
                               graphics=False))
    async with app.run_test(size=SIZE) as pilot:
        await opened(pilot, app)
        await wait_for(pilot, lambda: isinstance(app.screen, RigScreen), "the rig step")
        await wait_for(pilot, lambda: len(readings_of(session.path)["T1"]) >= 3,
                       "three shots saved on the rig step")
        await wait_for(pilot, lambda: "-> T1" in laser(app), "said where they went")
        await pilot.press("n")
        await wait_for(pilot, lambda: isinstance(app.screen, PositionScreen), "the left step")
        count = len(readings_of(session.path)["T1"])
        await wait_for(pilot, lambda: len(readings_of(session.path)["T1"]) > count,
                       "shots saved on the left step too")
        assert "connected" in laser(app)


@synchronous
async def test_shots_without_a_target_are_held_said_and_saved_once_one_is_marked(
        demo: Demo) -> None:
    session = framed(demo, "held", reading=False)
    set_field_step(session.path, "back")
    app = FieldApp(FieldConfig(capture=demo.capture, session=session.path, graphics=False,
                               port="sim://trupulse?interval=0.1&distance=201.5"))
    async with app.run_test(size=SIZE) as pilot:
        await opened(pilot, app)
        await wait_for(pilot, lambda: isinstance(app.screen, PositionScreen)
                       and "held: mark or select a target" in laser(app),
                       "the held shots said on the back step")
        await pilot.press("n")
        await wait_for(pilot, lambda: isinstance(app.screen, TargetsScreen)
                       and app.screen.query_one(PixelView).cursor is not None, "the targets")
        held = len(app.laser.held())
        await pilot.press("enter")
        await wait_for(pilot, lambda: len(readings_of(session.path).get("T1", [])) >= held,
                       "the held shots saved to T1")
        await pilot.press("q", "q")  # asked first if shots are still held
    saved = len(readings_of(session.path)["T1"])
    logged = (session.path / "history.log").read_text().count("held, not saved")
    assert saved >= held and saved + logged >= held


# -- 3. a held frame is filed only by its own keys --------------------------------------------


@synchronous
async def test_a_frame_of_another_scene_is_filed_only_by_its_own_keys(demo: Demo) -> None:
    """Before: a held frame stayed held after a later frame's checks replaced its
    question, the next ``n`` filed it into the right position, and "add it to the right
    position" was the first thing offered for a frame of another scene."""
    session, app = watching_app(demo)
    async with app.run_test(size=SIZE) as pilot:
        await opened(pilot, app)
        await take_the_left_frame(pilot, app, demo)
        other_scene(demo.card / "DSCN0002.PNG", demo.scene / "left.png")
        await wait_for(pilot, lambda: "does not match the left burst" in
                       side(app).replace("\n", " "), "the question")
        question = side(app)
        assert question.index("Esc: leave it on the card") < question.index("f: add it to")
        await wait_for(pilot, lambda: {"a", "f", "escape"} <= key_bar(app),
                       "the question's own keys in the key bar", 5)
        write_frame(demo.card / "DSCN0003.PNG", demo.scene / "left.png", iso=100)
        await wait_for(pilot, lambda: "frame DSCN0003.PNG (left frame 2 of 2)" in side(app),
                       "the next left frame's checks")
        assert "does not match" in side(app)  # still asked, still shown
        await pilot.press("n")
        await wait_for(pilot, lambda: app.screen.position == "right", "the right step")
        await pilot.pause(1.0)
    saved = load_session(session)
    assert not frames_at(saved, "right")
    assert [Path(f.file).name for f in frames_at(saved, "left")] == ["DSCN0001.PNG",
                                                                      "DSCN0003.PNG"]
    assert not (session / "raw" / "DSCN0002.PNG").exists()  # left on the card


# -- 4. the verdict uses the screen ---------------------------------------------------------


@synchronous
async def test_the_verdict_grows_with_the_terminal_scrolls_by_keys_and_says_the_redo_first(
        demo: Demo) -> None:
    """Before: a verdict box of 6 lines at any height, scrolled by no key, with the scale
    line that named the fault ("re-tape C_lb") written last."""
    session = framed(demo, "verdict")
    typo = replace(READING, slope_distance_m=2000.0)
    targets = tuple(Target(name=f"T{i}", pixel=(60.0 + 40 * i, 140.0), window_px=9,
                           readings=(replace(READING, slope_distance_m=190.0), READING, typo))
                    for i in range(1, 7))
    save_session(replace(load_session(session.path), targets=targets))
    set_field_step(session.path, "process")
    process_session(session.path, new_run_id())
    app = app_on(demo, session.path)
    async with app.run_test(size=(80, 44)) as pilot:
        await opened(pilot, app)
        await wait_for(pilot, lambda: "latest run shown" in text(app, "#stage"), "the run")
        box = app.screen.query_one("#verdict-box")
        assert box.region.height > 10  # grows with the terminal
        lines = text(app, "#verdict").splitlines()
        assert "targets within" in lines[0] and lines[1].startswith("redo: ")
        await wait_for(pilot, lambda: "down" in key_bar(app), "↑↓ in the key bar", 5)
        await pilot.resize_terminal(80, 24)
        await pilot.pause(0.2)
        assert box.max_scroll_y > 0
        await pilot.press("down", "down")
        assert box.scroll_y > 0


# -- 5. r during the automatic run ------------------------------------------------------------


@pytest.mark.slow
@synchronous
async def test_r_during_the_run_neither_cancels_it_nor_reports_it_busy(demo: Demo,
                                                                         monkeypatch) -> None:
    """Before: ``r`` answered "busy: being processed by PID <its own>", cancelled the
    first run, and nothing ran."""
    import rigkit.batch.session as batch_session
    import rigkit.tui.screens.process as process_screen

    monkeypatch.setattr(batch_session, "BRIEF_HOLD_S", 0.0)  # a stage longer than its wait
    run = process_screen.process_session

    def slow(path, run_id, progress):  # each stage 0.2 s longer: r lands inside the run
        def slowed(stage: str, fraction: float) -> None:
            time.sleep(0.2)
            progress(stage, fraction)

        return run(path, run_id, progress=slowed)

    monkeypatch.setattr(process_screen, "process_session", slow)
    session, app = app_at(demo, "r-twice", "targets")
    async with app.run_test(size=SIZE) as pilot:
        await opened(pilot, app)
        await wait_for(pilot, lambda: isinstance(app.screen, TargetsScreen), "the targets")
        await pilot.press("n")
        await wait_for(pilot, lambda: isinstance(app.screen, ProcessScreen)
                       and "%" in text(app, "#stage"), "the automatic run under way", 60)
        await pilot.press("r")
        await wait_for(pilot, lambda: "targets within" in text(app, "#verdict")
                       or "✘" in text(app, "#stage"), "the verdict", 90)
        assert "busy" not in text(app, "#stage") and "targets within" in text(app, "#verdict")


# -- 6. the taped scale as the profile gives it -------------------------------------------------


@synchronous
async def test_c_lb_is_printed_as_the_profile_gives_it(demo: Demo) -> None:
    """Before: "C_lb = 2.0 m" for a profile's 2.03 m."""
    rig = yaml.safe_load(demo.rig.read_text())
    rig["baselines"]["C_lb"]["value_m"] = 2.03
    (demo.root / "rig-203.yaml").write_text(yaml.safe_dump(rig))
    session = create_session(demo.capture / "taped", demo.root / "rig-203.yaml")
    for position in ("left", "back"):
        session = add_position_frame(session, position, demo.scene / f"{position}.png")
    set_field_step(session.path, "back")
    app = app_on(demo, session.path)
    async with app.run_test(size=SIZE) as pilot:
        await opened(pilot, app)
        shown = await take_position(pilot, app, "back")
        assert "at C_lb = 2.03 m" in shown
        await pilot.press("b", "b", "b")
        await wait_for(pilot, lambda: isinstance(app.screen, RigScreen), "the rig")
        assert "C_lb 2.03 m" in text(app, "#rig")


# -- 7. stale and contradictory status --------------------------------------------------------


@synchronous
async def test_a_reading_replaces_the_quiet_note(demo: Demo) -> None:
    """Before: "nothing received in 10 s" stayed up while readings arrived."""
    from rigkit.rangefinder.driver import LineStats
    from rigkit.tui.app import LinkNews

    session = framed(demo, "quiet", reading=False)
    add_target(session, "T1", (190.0, 140.0))
    set_field_step(session.path, "targets")
    app = app_on(demo, session.path)
    async with app.run_test(size=SIZE) as pilot:
        await opened(pilot, app)
        await wait_for(pilot, lambda: isinstance(app.screen, TargetsScreen), "the targets")
        app.post_message(LinkNews(LinkStatus(True, quiet_note(LineStats(), "trupulse", 10.0))))
        await wait_for(pilot, lambda: "nothing received" in laser(app), "the note")
        app.post_message(LinkNews(replace(READING, source="trupulse:/dev/rfcomm0")))
        await wait_for(pilot, lambda: "newest reading" in laser(app), "the reading")
        assert "nothing received" not in laser(app)


def test_burst_advice_is_one_answer_for_one_shown_measurement(demo: Demo) -> None:
    """Before: "take 1 frames" then "take 2" for the same 0.08 px."""
    from rigkit.pipeline.shimmer import Shimmer
    from rigkit.rig.bursts import burst_advice
    from rigkit.rig.profile import load_rig

    profile = load_rig(demo.rig)
    said = {burst_advice(profile, Shimmer(rms, 15.0, 0.01, 500), "left frames 1 and 2", 200.0)
            for rms in (0.0101, 0.0125, 0.0149)}  # all "0.01 px" (4, 6 and 8 frames before)
    assert len(said) == 1
    line, need = said.pop()
    assert "0.01 px RMS" in line and f"take {need} frames per position" in line
    one = burst_advice(profile, Shimmer(0.001, 15.0, 0.01, 500), "left frames 1 and 2", 200.0)
    assert one[1] == 1 and "take 1 frame per position" in one[0]


@synchronous
async def test_a_right_frame_at_back_is_told_to_move_not_to_retape(demo: Demo) -> None:
    """Before: a right frame arriving at BACK got advice about C_lb and the zoom."""
    session = create_session(demo.capture / "swapped", demo.rig)
    for position in ("left", "right"):
        session = add_position_frame(session, position, demo.scene / f"{position}.png")
    set_field_step(session.path, "back")
    app = app_on(demo, session.path, watch=demo.card)
    async with app.run_test(size=SIZE) as pilot:
        await opened(pilot, app)
        await wait_for(pilot, lambda: isinstance(app.screen, PositionScreen), "the back step")
        write_frame(demo.card / "DSCN0009.PNG", demo.scene / "right.png", iso=100)
        shown = await take_position(pilot, app, "back")
        redo = next(line for line in shown.splitlines() if line.startswith("redo:"))
        assert "behind the LEFT position" in redo and "zoom" not in redo


@synchronous
async def test_c_on_a_frame_the_watcher_is_taking_files_it_once_without_a_word(
        demo: Demo) -> None:
    """Before: ``c`` on a card frame the watcher was about to ingest gave a red "given
    twice in the burst" though it was filed once."""
    session = create_session(demo.capture / "card-race", demo.rig).path
    app = FieldApp(FieldConfig(capture=demo.capture, session=session, watch=demo.card,
                               graphics=False, settle_s=1.0))
    async with app.run_test(size=SIZE) as pilot:
        await opened(pilot, app)
        await wait_for(pilot, lambda: isinstance(app.screen, RigScreen), "the rig")
        write_frame(demo.card / "DSCN0001.PNG", demo.scene / "left.png")
        await pilot.press("n")  # the left step lists it on the card before it settles
        await wait_for(pilot, lambda: isinstance(app.screen, PositionScreen)
                       and "DSCN0001.PNG" in text(app, "#card"), "the card's frame offered")
        await pilot.press("c")
        await take_position(pilot, app, "left")
        await pilot.pause(2.5)  # the watcher's own arrival of it comes and goes
        assert "twice" not in side(app) and "✘" not in side(app)
    assert len(frames_at(load_session(session), "left")) == 1


@synchronous
async def test_a_reading_is_dropped_only_on_a_second_x(demo: Demo) -> None:
    """Before: ``x`` dropped a laser reading at one press while every other delete asked."""
    session, app = app_at(demo, "x-once", "targets")
    async with app.run_test(size=SIZE) as pilot:
        await opened(pilot, app)
        await wait_for(pilot, lambda: isinstance(app.screen, TargetsScreen), "the targets")
        await pilot.press("x")
        await pilot.pause(0.2)
        assert readings_of(session.path) == {"T1": [200.0]}
        await pilot.press("x")
        await wait_for(pilot, lambda: readings_of(session.path) == {"T1": []}, "the drop")


@synchronous
async def test_one_port_for_the_whole_run_never_in_use_by_ourselves(demo: Demo) -> None:
    """Before: every visit of the targets step opened the port again, and was told
    "port in use by another program" while the earlier visit's listener held it."""
    from rigkit.rangefinder.sim import PtySimulator, SimConfig

    session = framed(demo, "one-port")
    set_field_step(session.path, "targets")
    with PtySimulator(SimConfig(interval=0.2, distance=200.5)) as sim:
        app = FieldApp(FieldConfig(capture=demo.capture, session=session.path, port=sim.path,
                                   graphics=False))
        said: list[str] = []
        async with app.run_test(size=SIZE) as pilot:
            await opened(pilot, app)
            for _ in range(4):
                await wait_for(pilot, lambda: isinstance(app.screen, TargetsScreen),
                               "the targets")
                await pilot.pause(0.3)
                said.append(laser(app))
                await pilot.press("n")
                await wait_for(pilot, lambda: isinstance(app.screen, ProcessScreen), "process")
                said.append(laser(app))
                await pilot.press("b")
            await wait_for(pilot, lambda: len(readings_of(session.path)["T1"]) >= 4, "shots")
    assert not any("in use" in line for line in said), said


@synchronous
async def test_a_deleted_targets_name_is_never_given_again(demo: Demo) -> None:
    session, app = app_at(demo, "names", "targets", reading=False)
    async with app.run_test(size=SIZE) as pilot:
        await opened(pilot, app)
        await wait_for(pilot, lambda: isinstance(app.screen, TargetsScreen)
                       and app.screen.query_one(PixelView).cursor is not None, "the left view")
        await pilot.press("enter", "right", "right", "enter", "d", "d")  # T1, T2; T2 deleted
        await wait_for(pilot, lambda: list(readings_of(session.path)) == ["T1"], "T2 deleted")
        await pilot.press("left", "enter")
        await wait_for(pilot, lambda: len(readings_of(session.path)) == 2, "a new target")
    assert list(readings_of(session.path)) == ["T1", "T3"]


@synchronous
async def test_a_typed_range_that_would_be_a_stray_is_asked_and_strays_are_marked(
        demo: Demo) -> None:
    """Before: 209 typed after 200.0 (4.5 %) was kept as "2 stray", neither marked."""
    session, app = app_at(demo, "stray", "targets")
    async with app.run_test(size=SIZE) as pilot:
        await opened(pilot, app)
        await wait_for(pilot, lambda: isinstance(app.screen, TargetsScreen), "the targets")
        await pilot.press("m", *"209", "enter")
        await pilot.pause(0.3)
        assert readings_of(session.path) == {"T1": [200.0]}  # asked first
        await pilot.press("m", *"209", "enter")  # typed again: kept, and marked
        await wait_for(pilot, lambda: readings_of(session.path) == {"T1": [200.0, 209.0]},
                       "the second reading")
        await wait_for(pilot, lambda: text(app, "#readings").count("stray") == 2, "marked")


# -- 8. a frame's arrival shows at once; checks in arrival order ----------------------------


@synchronous
async def test_an_arrival_shows_before_its_comparison_and_checks_go_in_order(
        demo: Demo, monkeypatch) -> None:
    """Before: for burst frames 2 and later nothing showed until the burst comparison was
    done (3-5 s at full resolution); two frames landing together were checked side by
    side and the screen did not say which."""
    import rigkit.capture.field as field

    compare = field.burst_misfit

    def slow(*args, **kwargs):
        time.sleep(1.5)
        return compare(*args, **kwargs)

    monkeypatch.setattr(field, "burst_misfit", slow)
    shown: list[str] = []  # every status the screen shows, in order (a look every
    # 50 ms missed one that lasted less on a loaded machine)
    status = PositionScreen._status

    def recorded(screen: PositionScreen, markup: str) -> None:
        shown.append(markup)
        status(screen, markup)

    monkeypatch.setattr(PositionScreen, "_status", recorded)
    session, app = watching_app(demo)
    async with app.run_test(size=SIZE) as pilot:
        await opened(pilot, app)
        await take_the_left_frame(pilot, app, demo)
        write_frame(demo.card / "DSCN0002.PNG", demo.scene / "left.png", iso=100)
        start = time.monotonic()
        await wait_for(pilot, lambda: "DSCN0002.PNG arrived" in side(app), "the arrival", 5)
        assert time.monotonic() - start < SETTLE_S + 1.2  # before the 1.5 s comparison
        write_frame(demo.card / "DSCN0003.PNG", demo.scene / "left.png", iso=200)
        await wait_for(pilot, lambda: "(left frame 3 of 3)" in side(app), "the third frame", 30)
    second = next(i for i, s in enumerate(shown) if "left frame 2" in s)
    third = next(i for i, s in enumerate(shown) if "DSCN0003.PNG: left frame 3" in s)
    assert second < third, shown
    assert [Path(f.file).name for f in frames_at(load_session(session), "left")] == \
        ["DSCN0001.PNG", "DSCN0002.PNG", "DSCN0003.PNG"]


# -- 9. text that fits and says what to do ---------------------------------------------------


@synchronous
async def test_ctrl_c_quits_as_the_key_bar_says_q_does(demo: Demo) -> None:
    """Before: Ctrl-C said "Press ctrl+q to quit" while the key bar said q."""
    session = framed(demo, "ctrl-c")
    app = app_on(demo, session.path)
    async with app.run_test(size=SIZE) as pilot:
        await opened(pilot, app)
        await wait_for(pilot, lambda: isinstance(app.screen, (PositionScreen, RigScreen,
                                                               TargetsScreen, ProcessScreen)),
                       "a step")
        await pilot.press("ctrl+c")
        await pilot.pause(0.3)
        assert not app.is_running
    assert app.return_code in (None, 0)


@synchronous
async def test_e_before_processing_says_press_r(demo: Demo) -> None:
    """Before: ``e`` before processing said to run a shell command."""
    session, app = app_at(demo, "e-first", "process")
    async with app.run_test(size=SIZE) as pilot:
        await opened(pilot, app)
        await wait_for(pilot, lambda: "not processed yet" in text(app, "#stage"), "the step")
        await pilot.press("e")
        await pilot.pause(0.2)
        said = " ".join(str(n.message) for n in app._notifications)
        assert "press r" in said and "rigkit process" not in text(app, "#stage")


@synchronous
async def test_the_position_keys_are_in_the_key_bar_and_the_checks_fit(demo: Demo) -> None:
    """Before: ``c`` was missing from the key bar, the check lines were cut once the card
    line showed at 80x24, and the back view's scale line was hidden at 60x20."""
    session = framed(demo, "fit", reading=False)
    write_frame(demo.card / "DSCN0007.PNG", demo.scene / "right.png")  # on the card
    set_field_step(session.path, "back")
    app = app_on(demo, session.path, watch=demo.card)
    async with app.run_test(size=(60, 20)) as pilot:
        await opened(pilot, app)
        await take_position(pilot, app, "back")
        await wait_for(pilot, lambda: "DSCN0007" in text(app, "#card"), "the card line")
        await wait_for(pilot, lambda: {"o", "c", "x", "n", "b", "q"} <= key_bar(app),
                       "the position's keys in the key bar")  # drawn after the bindings change
        line = next(w for w in app.screen.query("#checks"))
        side_panel = app.screen.query_one("#side")
        assert "× → ~" in text(app, "#checks")
        side_panel.scroll_end(animate=False)
        await pilot.pause(0.1)
        assert text(app, "#card") and line.region.height > 0  # all of it reachable


@synchronous
async def test_a_frame_that_does_not_match_is_said_in_plain_words(demo: Demo) -> None:
    """Before: "left/other: only 8 of 49 feature matches agree on one alignment"."""
    session = create_session(demo.capture / "plain", demo.rig)
    session = add_position_frame(session, "left", demo.scene / "left.png")
    set_field_step(session.path, "right")
    app = app_on(demo, session.path, watch=demo.card)
    async with app.run_test(size=SIZE) as pilot:
        await opened(pilot, app)
        await wait_for(pilot, lambda: isinstance(app.screen, PositionScreen), "the right step")
        other_scene(demo.card / "DSCN0004.PNG", demo.scene / "left.png")
        shown = await take_position(pilot, app, "right")
        assert "does not match the left one" in shown
        assert not re.search(r"feature matches|left/other", shown)


# -- 10. the demo, and the first screen ------------------------------------------------------


@synchronous
async def test_the_demo_fires_only_where_there_will_be_depth(demo: Demo) -> None:
    """Before: the demo's laser fired at any pixel, the top-left corner (no depth there)
    included, and only the final verdict said "no estimate"."""
    session = load_session(demo.session)
    for position in ("left", "right", "back"):
        session = add_position_frame(session, position, demo.scene / f"{position}.png")
    set_field_step(session.path, "targets")
    app = FieldApp(FieldConfig(capture=demo.capture, session=session.path, demo=demo,
                               graphics=False))
    async with app.run_test(size=SIZE) as pilot:
        await opened(pilot, app)
        await wait_for(pilot, lambda: isinstance(app.screen, TargetsScreen)
                       and app.screen.query_one(PixelView).cursor is not None, "the left view")
        await pilot.press(*["shift+left"] * 30, *["shift+up"] * 30, "enter")
        await pilot.pause(1.0)
        said = " ".join(str(n.message) for n in app._notifications)
        assert "no depth will be estimated there" in said
        assert readings_of(session.path) == {"T1": []}


def test_the_demos_laser_gives_directions_that_georeference_its_export(
        demo_scene: Demo, tmp_path: Path) -> None:
    """Before: the demo's laser sent one fixed direction, so its export could not be
    put on the map."""
    from rigkit.capture import utc_now
    from rigkit.export import DEFAULT_FORMATS, export_path
    from rigkit.rangefinder.sim import SimConfig, parse_sim_url

    demo = Demo(tmp_path / "d", demo_scene.seed, 0.1, demo_scene.size, demo_scene.burst)
    shutil.copytree(demo_scene.scene, demo.scene)
    shutil.copy(demo_scene.rig, demo.rig)
    demo.prepare()
    session = load_session(demo.session)
    assert session.tripod is not None
    for position in ("left", "right", "back"):
        session = add_position_frame(session, position, demo.scene / f"{position}.png")
    width, height = demo.size
    for name, pixel in (("T1", (0.3 * width, 0.6 * height)), ("T2", (0.75 * width, 0.7 * height)),
                        ("T3", (0.55 * width, 0.45 * height))):
        assert demo.no_depth(pixel) == "", name
        sim: SimConfig = parse_sim_url(demo.laser_url(pixel))
        reading = LaserReading(sim.distance, utc_now(), "trupulse:sim",
                               inclination_deg=sim.inclination, azimuth_deg=sim.azimuth)
        session = add_target(session, name, pixel, readings=[reading])
    process_session(session.path, new_run_id())
    done = export_path(session.path, tmp_path / "export", DEFAULT_FORMATS)
    assert done.georef is not None


def test_the_app_imports_no_heavy_library_before_its_first_screen() -> None:
    """Before: importing the app took the pipeline, OpenCV, SciPy (the demo's renderer)
    and every screen, ~0.8 s of CPU before anything was drawn; the demo's scene was
    rendered before the terminal showed anything."""
    code = ("import sys, rigkit.commands.field_run, rigkit.tui.app\n"
            "heavy = [m for m in ('cv2', 'scipy', 'rawpy', 'rigkit.capture.views', "
            "'rigkit.tui.screens', 'rigkit.synth', 'rigkit.batch') if m in sys.modules]\n"
            "print(heavy)")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          timeout=120)
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip() == "[]"


@synchronous
async def test_the_demo_shows_a_screen_while_its_scene_renders(tmp_path: Path,
                                                               monkeypatch) -> None:
    import rigkit.synth.demo as demo_module

    rendering: list[bool] = []

    def slow_render(demo: Demo) -> None:
        rendering.append(True)
        time.sleep(3.0)
        raise OSError(28, "No space left on device")  # and the error is said, no crash

    monkeypatch.setattr(demo_module, "render_demo", slow_render)
    demo = Demo(tmp_path / "demo")
    app = FieldApp(FieldConfig(capture=demo.capture, session=demo.session, demo=demo,
                               graphics=False))
    async with app.run_test(size=SIZE) as pilot:
        await pilot.pause(0.5)
        assert rendering and "rendering the demo scene" in text(app, "#opening")
        await wait_for(pilot, lambda: "No space left" in text(app, "#opening"), "the error")
        await pilot.press("q")
    assert app._exception is None
