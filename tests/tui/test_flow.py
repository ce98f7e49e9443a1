"""Pilot tests of ``rigkit field``: the demo flow from frames to the verdict, checks that
fail as they should, typed ranges, and quitting mid-flow then resuming."""

from __future__ import annotations

import hashlib
import re
import shutil
from pathlib import Path

import pytest

from rigkit.capture import POSITIONS, Session, create_session, load_session, read_rows
from rigkit.capture.field import add_position_frame, frames_at
from rigkit.synth.demo import Demo
from rigkit.synth.io import frame_name
from rigkit.tui.app import FieldApp
from rigkit.tui.config import FieldConfig
from rigkit.tui.screens import (
    PositionScreen,
    ProcessScreen,
    RigScreen,
    StartScreen,
    TargetsScreen,
)
from rigkit.tui.widgets import PixelView
from tests.tui.conftest import SETTLE_S, opened, side, synchronous, text, wait_for, write_frame

SIZE = (80, 24)


def taken(session: Session) -> list[str]:
    """The positions that have a frame."""
    return [p for p in POSITIONS if frames_at(session, p)]


def demo_app(demo: Demo) -> FieldApp:
    return FieldApp(FieldConfig(capture=demo.capture, session=demo.session,
                                demo=demo, graphics=False, settle_s=SETTLE_S))


def watching_app(demo: Demo) -> tuple[Path, FieldApp]:
    """A new session "field-1" and the app on it, watching the demo's card folder for
    frames (no simulated camera: the test writes them)."""
    session = create_session(demo.capture / "field-1", demo.rig).path
    return session, FieldApp(FieldConfig(capture=demo.capture, session=session,
                                         watch=demo.card, graphics=False, settle_s=SETTLE_S))


async def take_position(pilot, app: FieldApp, position: str, frames: int = 1) -> str:
    """Wait on ``position``'s screen until its ``frames``-th frame (or a later one: the
    demo's camera shoots a burst) is checked; return what the side panel says."""
    await wait_for(pilot, lambda: isinstance(app.screen, PositionScreen)
                   and app.screen.position == position, f"the {position} screen")
    numbered = re.compile(rf"\({position} frame (\d+)(?: of \d+)?\)")

    def checked() -> bool:
        shown = side(app)
        if not app.screen.query("#status"):  # the screen before issue 49: marks, one frame
            return "checking" not in shown and ("✔" in shown or "✘" in shown)
        return any(int(n) >= frames for n in numbered.findall(shown))

    await wait_for(pilot, checked, f"the {position} frame {frames}'s checks")
    return side(app)


async def take_the_left_frame(pilot, app: FieldApp, demo: Demo) -> None:
    """From the rig screen on to LEFT, and the demo's left view arriving on the card."""
    await pilot.press("n")
    await wait_for(pilot, lambda: isinstance(app.screen, PositionScreen), "the left screen")
    write_frame(demo.card / "DSCN0001.PNG", demo.scene / "left.png")
    await take_position(pilot, app, "left")


async def mark_target(pilot, app: FieldApp, moves: list[str], readings: int) -> None:
    await pilot.press(*moves, "enter")
    count = len(app.session.targets)  # type: ignore[union-attr]
    await wait_for(pilot, lambda: len(app.session.targets[count - 1].readings) >= readings,
                   f"{readings} readings of T{count}")


@pytest.mark.slow
@synchronous
async def test_demo_flow_from_frames_to_verdict(demo: Demo) -> None:
    app = demo_app(demo)
    async with app.run_test(size=SIZE) as pilot:
        await opened(pilot, app)
        assert isinstance(app.screen, RigScreen)
        assert "focal length" in text(app, "#rig")
        await pilot.press("n")
        left = await take_position(pilot, app, "left", demo.burst)  # a burst, shimmer measured
        assert "no EXIF" in left and "heat shimmer" in left and "✘" not in left
        await pilot.press("n")
        right = await take_position(pilot, app, "right", demo.burst)
        assert "✘" not in right and "parallax" in right
        await pilot.press("n")
        back = await take_position(pilot, app, "back", demo.burst)
        assert "✘" not in back and "× → ~" in back and "at C_lb = 2 m" in back
        await pilot.press("n")
        await wait_for(pilot, lambda: isinstance(app.screen, TargetsScreen)
                       and app.screen.query_one(PixelView).cursor is not None, "the left view")
        await mark_target(pilot, app, ["right", "right", "down"], 3)
        await mark_target(pilot, app, ["left"] * 6 + ["up"] * 4, 3)
        await wait_for(pilot, lambda: "-> T2" in text(app, "LaserLine"), "the shots saved")
        assert "T2" in text(app, "#targets")
        await pilot.press("n")
        await wait_for(pilot, lambda: isinstance(app.screen, ProcessScreen)
                       and "targets within" in text(app, "#verdict"), "the verdict", 60)
        assert app.screen.query_one("#rows").row_count == 2
        await pilot.press("e")  # export: no tripod position, so in the camera frame
        await wait_for(pilot, lambda: "points in the camera frame" in text(app, "#stage"),
                       "the export", 30)
        await pilot.press("q")
    assert sorted(p.name for p in (demo.session / "export").iterdir()) == [
        ".rigkit-outputs", f"{demo.session.name}.export.json", f"{demo.session.name}.las",
        f"{demo.session.name}.ply"]
    session = load_session(demo.session)
    assert taken(session) == ["left", "right", "back"]
    assert [len(t.readings) for t in session.targets] == [3, 3]
    assert all(r.source.startswith("trupulse:sim://") for r in session.targets[0].readings)
    assert (demo.session / "results" / "depth.npy").is_file()
    for index, position in enumerate(("left", "right", "back")):  # originals untouched
        files = [Path(f.file).name for f in frames_at(session, position)]
        assert files == [f"DSCN{100 + 10 * index + k:04d}.PNG" for k in range(demo.burst)]
        for k, frame in enumerate(frames_at(session, position)):
            card = (demo.card / files[k]).read_bytes()
            assert card == (demo.scene / frame_name(position, k)).read_bytes()
            assert hashlib.sha256(card).hexdigest() == frame.sha256


@pytest.mark.slow
@synchronous
async def test_checks_catch_a_duplicate_frame_and_an_exif_mismatch(demo: Demo) -> None:
    session, app = watching_app(demo)
    async with app.run_test(size=SIZE) as pilot:
        await opened(pilot, app)
        await pilot.press("n")
        await wait_for(pilot, lambda: isinstance(app.screen, PositionScreen), "the left screen")
        write_frame(demo.card / "DSCN0001.PNG", demo.scene / "left.png", iso=100)
        assert "EXIF agrees" in await take_position(pilot, app, "left")
        await pilot.press("n")
        await wait_for(pilot, lambda: app.screen.position == "right", "the right screen")
        shutil.copy(demo.card / "DSCN0001.PNG", demo.card / "DSCN0002.PNG")
        await wait_for(pilot, lambda: "same file" in side(app), "the refusal")
        checks = side(app)
        assert "DSCN0002.PNG is the same file as raw/DSCN0001.PNG, given for left and right" in \
            checks.replace("\n", " ")
        assert not frames_at(load_session(session), "right")  # refused on arrival
        write_frame(demo.card / "DSCN0003.PNG", demo.scene / "right.png", iso=400)
        await wait_for(pilot, lambda: "frame DSCN0003" in side(app) and "✘" in
                       side(app), "the EXIF mismatch")
        checks = side(app)
        assert "ISO 400 differs from the left frame's ISO 100" in checks and "redo:" in checks
        write_frame(demo.card / "DSCN0004.PNG", demo.scene / "right.png", iso=100)
        await wait_for(pilot, lambda: "frame DSCN0004" in side(app) and "parallax" in
                       side(app), "the good right frame")
        assert "✘" not in side(app)
    recorded = load_session(session)
    assert frames_at(recorded, "right")[-1].file == "raw/DSCN0004.PNG"
    # The refused copy never entered raw/; the frame that failed its check is kept.
    assert sorted(p.name for p in (session / "raw").iterdir()) == \
        ["DSCN0001.PNG", "DSCN0003.PNG", "DSCN0004.PNG"]


@pytest.mark.slow
@synchronous
async def test_quit_mid_flow_resumes_where_it_stopped(demo: Demo) -> None:
    app = demo_app(demo)
    async with app.run_test(size=SIZE) as pilot:
        await opened(pilot, app)
        await pilot.press("n")
        await take_position(pilot, app, "left")
        await pilot.press("n")
        await take_position(pilot, app, "right")
        await pilot.press("q")
    assert taken(load_session(demo.session)) == ["left", "right"]
    app = demo_app(demo)
    async with app.run_test(size=SIZE) as pilot:
        await opened(pilot, app)
        await wait_for(pilot, lambda: isinstance(app.screen, PositionScreen)  # where it stopped
                       and app.screen.position == "right" and "parallax" in side(app),
                       "the right frame's checks")  # (the demo's burst may have added more)
        await pilot.press("n")
        assert "✘" not in await take_position(pilot, app, "back")
    assert taken(load_session(demo.session)) == ["left", "right", "back"]


@pytest.mark.slow
@synchronous
async def test_typed_ranges_and_a_verdict_that_asks_for_more(demo: Demo) -> None:
    session = create_session(demo.capture / "typed", demo.rig)
    for position in ("left", "right", "back"):
        session = add_position_frame(session, position, demo.scene / f"{position}.png")
    app = FieldApp(FieldConfig(capture=demo.capture, session=session.path, graphics=False))
    async with app.run_test(size=SIZE) as pilot:
        await opened(pilot, app)
        await wait_for(pilot, lambda: isinstance(app.screen, TargetsScreen)
                       and app.screen.query_one(PixelView).cursor is not None, "the left view")
        assert "no rangefinder port" in text(app, "LaserLine")
        await pilot.press("m")  # no target yet: nothing to type a range for
        assert not app.screen.query_one("#range").display
        await pilot.press("enter", "m", *"abc", "enter", "q")  # T1 marked, no reading
    assert [t.name for t in load_session(session.path).targets] == ["T1"]
    app = FieldApp(FieldConfig(capture=demo.capture, session=session.path, graphics=False))
    async with app.run_test(size=SIZE) as pilot:
        await opened(pilot, app)
        await wait_for(pilot, lambda: isinstance(app.screen, TargetsScreen)
                       and "T1" in text(app, "#targets"), "the targets, resumed")
        await pilot.press("m", *"160", "enter")  # far from the true ~200 m
        assert [r.slope_distance_m for r in app.session.targets[0].readings] == [160.0]
        assert app.session.targets[0].readings[0].source == "manual"
        await pilot.press("n")
        await wait_for(pilot, lambda: "targets within" in text(app, "#verdict"), "the verdict",
                       60)
        verdict = text(app, "#verdict")
        assert "0/1 targets within" in verdict and "capture again" in verdict
        assert re.search(r"T1: 2\d\.\d\d %: outside 1 %, outside the 2σ", verdict)
        # One laser 20 % off the tape: neither is fitted to the other; and the scale's source.
        assert re.search(r"scale: lasers: T1 and the tape's C_lb disagree .* 1 target cannot "
                         r"tell which is wrong", verdict, re.S)
        assert "rig scale: taped (C_lb 2.000 +- 0.000 m, not laser-calibrated)" in verdict
        await pilot.press("b", "m", *"200", "enter", "n")  # one more reading: run again
        await wait_for(pilot, lambda: len(runs(session.path)) == 2, "the second run", 60)
        await wait_for(pilot, lambda: "targets within" in text(app, "#verdict"), "the verdict")


def runs(session: Path) -> set[str]:
    """The run ids in a session's comparisons log."""
    log = session / "comparisons.csv"
    return {row.run_id for row in read_rows(log)} if log.is_file() else set()


@synchronous
async def test_start_screen_opens_a_session_or_starts_one(demo: Demo) -> None:
    app = FieldApp(FieldConfig(capture=demo.capture, graphics=False))
    async with app.run_test(size=SIZE) as pilot:
        await opened(pilot, app)
        await pilot.press("tab", *"ridge-9 nowhere.yaml", "enter")
        assert "nowhere.yaml" in text(app, "#message")
        assert not (demo.capture / "ridge-9").exists()
        # The rig's long temporary path set, not typed key by key (5 s of key presses);
        # typing into the field is what the line above does.
        app.screen.query_one("#new").value = f"ridge-9 {demo.rig}"
        await pilot.press("enter")
        await wait_for(pilot, lambda: isinstance(app.screen, RigScreen), "the new session's rig")
    assert load_session(demo.capture / "ridge-9").rig().name.startswith("synthetic")
    app = FieldApp(FieldConfig(capture=demo.capture, graphics=False))
    async with app.run_test(size=SIZE) as pilot:
        await opened(pilot, app)
        table = app.screen.query_one("#sessions")
        assert table.row_count == 2  # demo and ridge-9, sorted by name
        await pilot.press("down", "enter")
        await wait_for(pilot, lambda: isinstance(app.screen, RigScreen), "ridge-9 opened")
        assert app.session is not None and app.session.name == "ridge-9"


@synchronous
async def test_sessions_are_listed_by_folder_and_a_broken_one_says_why(demo: Demo) -> None:
    """Before: copies of one session were six rows of one name, a folder name was read
    as markup, and a broken session said "unreadable" and nothing more."""
    shutil.copytree(demo.session, demo.capture / "copy[b]x")
    broken = demo.capture / "broken"
    shutil.copytree(demo.session, broken)
    (broken / "session.yaml").write_text("format: nothing\n")
    app = FieldApp(FieldConfig(capture=demo.capture, graphics=False))
    async with app.run_test(size=SIZE) as pilot:
        await opened(pilot, app)
        table = app.screen.query_one("#sessions")
        names = [str(table.get_row_at(i)[0]) for i in range(table.row_count)]
        assert names == ["broken", "copy[b]x", demo.session.name]
        await pilot.press("enter")
        await wait_for(pilot, lambda: "session.yaml" in text(app, "#message"), "why")
        assert isinstance(app.screen, StartScreen)


@synchronous
async def test_a_new_session_stays_inside_the_capture_folder(demo: Demo) -> None:
    # Before: ``../../x`` or an absolute path created a session outside it.
    app = FieldApp(FieldConfig(capture=demo.capture, graphics=False))
    async with app.run_test(size=SIZE) as pilot:
        await opened(pilot, app)
        await pilot.press("tab")
        for name in ("../../escaped", str(demo.root / "abs")):
            app.screen.query_one("#new").value = f"{name} {demo.rig}"
            await pilot.press("enter")
            await wait_for(pilot, lambda: "session name" in text(app, "#message"),
                           f"the refusal of {name}")
    assert not (demo.root.parent / "escaped").exists() and not (demo.root / "abs").exists()


@synchronous
async def test_a_frame_declaring_a_huge_size_is_refused_and_the_app_goes_on(demo: Demo) -> None:
    # Before: a PNG header claiming 60000x60000 made the TUI exit.
    import struct

    session, app = watching_app(demo)
    async with app.run_test(size=SIZE) as pilot:
        await opened(pilot, app)
        await pilot.press("n")
        await wait_for(pilot, lambda: isinstance(app.screen, PositionScreen), "the left screen")
        data = bytearray((demo.scene / "left.png").read_bytes())
        data[16:24] = struct.pack(">II", 60000, 60000)
        (demo.card / "DSCN0001.PNG").write_bytes(bytes(data))
        await wait_for(pilot, lambda: "60000x60000" in side(app), "the refusal")
        write_frame(demo.card / "DSCN0002.PNG", demo.scene / "left.png", iso=100)
        await wait_for(pilot, lambda: "frame DSCN0002" in side(app) and "✔" in
                       side(app), "the good frame after it")
    assert [Path(f.file).name for f in frames_at(load_session(session), "left")] == \
        ["DSCN0002.PNG"]


# -- the field drive of issue 23: the TUI guards the operator -----------------------------


@synchronous
async def test_actions_name_the_selected_target_and_a_typo_never_becomes_a_reading(
    demo: Demo,
) -> None:
    # Before: m typed into the newest target whatever the cursor, the prompt named none,
    # and a typed 3000000 among good shots was averaged into 750,226 m.
    session = create_session(demo.capture / "field-1", demo.rig)
    for position in POSITIONS:
        session = add_position_frame(session, position, demo.scene / f"{position}.png")
    app = FieldApp(FieldConfig(capture=demo.capture, session=session.path, graphics=False))
    async with app.run_test(size=SIZE) as pilot:
        await opened(pilot, app)
        await wait_for(pilot, lambda: isinstance(app.screen, TargetsScreen)
                       and app.screen.query_one(PixelView).cursor is not None, "the left view")
        await pilot.press("enter", "right", "right", "enter")  # T1, then T2 (selected)
        await pilot.press("t")  # select T1
        assert "›T1" in text(app, "#targets")
        await pilot.press("m")
        assert "range to T1" in app.screen.query_one("#range").placeholder
        await pilot.press(*"250.4", "enter", "m", *"3000000", "enter")
        readings = {t.name: [r.slope_distance_m for r in t.readings]
                    for t in load_session(session.path).targets}
        assert readings == {"T1": [250.4], "T2": []}
        await pilot.press("x", "x")  # drop T1's newest reading (asked first)
        assert [len(t.readings) for t in load_session(session.path).targets] == [0, 0]
        shown = {b.binding.description for b in app.active_bindings.values()
                 if b.binding.show}
        assert {"aim", "mark", "select", "range", "drop"} <= shown  # the arrows in the footer


@synchronous
async def test_moving_on_without_a_reading_asks_first(demo: Demo) -> None:
    session = create_session(demo.capture / "field-1", demo.rig)
    for position in POSITIONS:
        session = add_position_frame(session, position, demo.scene / f"{position}.png")
    app = FieldApp(FieldConfig(capture=demo.capture, session=session.path, graphics=False))
    async with app.run_test(size=SIZE) as pilot:
        await opened(pilot, app)
        await wait_for(pilot, lambda: isinstance(app.screen, TargetsScreen), "the targets")
        await pilot.press("n")
        await pilot.pause(0.2)
        assert isinstance(app.screen, TargetsScreen)  # asked, not moved on
        await pilot.press("n")
        await wait_for(pilot, lambda: isinstance(app.screen, ProcessScreen), "processing")


@synchronous
async def test_a_failed_check_asks_before_moving_on(demo: Demo) -> None:
    # Before: n moved on after "the zoom changed" without a word.
    _, app = watching_app(demo)
    async with app.run_test(size=SIZE) as pilot:
        await opened(pilot, app)
        await take_the_left_frame(pilot, app, demo)
        await pilot.press("n")
        await wait_for(pilot, lambda: app.screen.position == "right", "the right screen")
        write_frame(demo.card / "DSCN0002.PNG", demo.scene / "back.png")  # no parallax
        await wait_for(pilot, lambda: "frame DSCN0002" in side(app)
                       and "✘" in side(app), "the failed check")
        await pilot.press("n")
        await pilot.pause(0.2)
        assert app.screen.position == "right"  # asked, not moved on
        await pilot.press("n")
        await wait_for(pilot, lambda: app.screen.position == "back", "the back screen")


@synchronous
async def test_a_frame_of_the_next_position_is_held_back_with_a_question(demo: Demo) -> None:
    # Before: a right frame dropped in before n joined the left burst with green ticks.
    session, app = watching_app(demo)
    async with app.run_test(size=SIZE) as pilot:
        await opened(pilot, app)
        await take_the_left_frame(pilot, app, demo)
        write_frame(demo.card / "DSCN0002.PNG", demo.scene / "right.png")  # too early
        await wait_for(pilot, lambda: "does not match the left burst" in
                       side(app).replace("\n", " "), "the question")
        assert len(frames_at(load_session(session), "left")) == 1
        await pilot.press("f")  # take it to the right position
        await wait_for(pilot, lambda: frames_at(load_session(session), "right"),
                       "the frame at the right position")
    assert [Path(f.file).name for f in frames_at(load_session(session), "right")] == \
        ["DSCN0002.PNG"]


@synchronous
async def test_next_past_empty_positions_reaches_targets_without_a_crash(demo: Demo) -> None:
    """Issue 37, item 1: `n` through LEFT, RIGHT and BACK with no frames used to end the
    app with an IndexError and exit status 0."""
    session, app = watching_app(demo)
    async with app.run_test(size=SIZE) as pilot:
        await opened(pilot, app)
        await wait_for(pilot, lambda: isinstance(app.screen, RigScreen), "the rig")
        for _ in range(4):
            await pilot.press("n")
            await pilot.pause()
        await wait_for(pilot, lambda: isinstance(app.screen, TargetsScreen)
                       and "no left frame yet" in text(app, "#note"), "the targets step")
        await pilot.press("q")
    assert app._exception is None


@synchronous
async def test_an_error_that_ends_the_app_is_status_1_and_logged(demo: Demo) -> None:
    from rigkit.tui.app import ended_by_error

    session, app = watching_app(demo)
    with pytest.raises(ZeroDivisionError):  # the test harness raises what ended the app
        async with app.run_test(size=SIZE) as pilot:
            await wait_for(pilot, lambda: isinstance(app.screen, RigScreen), "the rig")
            app.call_later(lambda: 1 / 0)  # a bug anywhere in the app
            await pilot.pause()
    assert ended_by_error(app) == 1
    assert "field        stopped by an internal error: ZeroDivisionError" in (
        session / "history.log").read_text()


@synchronous
async def test_a_retake_after_a_failed_frame_is_filed_where_it_was_taken(demo: Demo) -> None:
    """Issue 37, item 2: at RIGHT the left view taken again fails its parallax check;
    the correct right frame that follows used to be compared with the failed one, held
    as "taken from another position" and offered for the back position."""
    session, app = watching_app(demo)
    async with app.run_test(size=SIZE) as pilot:
        await opened(pilot, app)
        await take_the_left_frame(pilot, app, demo)
        await pilot.press("n")
        await wait_for(pilot, lambda: app.screen.position == "right", "the right screen")
        write_frame(demo.card / "DSCN0002.PNG", demo.scene / "left.png", iso=200)  # again
        await wait_for(pilot, lambda: "frame DSCN0002" in side(app)
                       and "✘" in side(app), "the failed parallax check")
        write_frame(demo.card / "DSCN0003.PNG", demo.scene / "right.png")
        await wait_for(pilot, lambda: "frame DSCN0003" in side(app), "the retake's checks")
        assert "does not match" not in side(app).replace("\n", " ")
    saved = load_session(session)
    assert [Path(f.file).name for f in frames_at(saved, "right")] == ["DSCN0003.PNG"]
    assert not frames_at(saved, "back")


@synchronous
async def test_a_typo_asks_first_and_x_drops_the_reading_under_the_cursor(demo: Demo) -> None:
    """Issue 37, items 3 and 5: 2011 typed for ~200 m is asked about before it is kept;
    x drops the reading under the readings cursor, not the newest; the panel lists what
    session.yaml holds; the target that gets the next shot says so."""
    session = create_session(demo.capture / "typo", demo.rig)
    for position in ("left", "right", "back"):
        session = add_position_frame(session, position, demo.scene / f"{position}.png")
    app = FieldApp(FieldConfig(capture=demo.capture, session=session.path, graphics=False))

    def readings() -> list[float]:
        return [r.slope_distance_m for r in load_session(session.path).targets[0].readings]

    async with app.run_test(size=SIZE) as pilot:
        await opened(pilot, app)
        await wait_for(pilot, lambda: isinstance(app.screen, TargetsScreen)
                       and app.screen.query_one(PixelView).cursor is not None, "the left view")
        await pilot.press("enter")  # T1
        assert "T1" in text(app, "#targets") and "← next shot" in text(app, "#targets")
        await pilot.press("m", *"2011", "enter")
        await pilot.pause()
        assert readings() == []  # asked, not kept
        await pilot.press("m", *"2011", "enter")  # typed again: kept
        await pilot.press("m", *"200.5", "enter", "m", *"200.5", "enter")
        await wait_for(pilot, lambda: readings() == [2011.0, 200.5], "both readings")
        await pilot.press("left_square_bracket", "x", "x")  # the older one, under the cursor
        await wait_for(pilot, lambda: readings() == [200.5], "the typo dropped")
        panel = text(app, "#readings")
        assert "200.50 m" in panel and "2011.00" not in panel
        await pilot.press("q")


@pytest.mark.slow
@synchronous
async def test_the_verdict_shows_stray_readings_as_process_does(demo: Demo) -> None:
    """Issue 37, item 8: `rigkit process` printed stray-reading warnings the TUI's
    verdict did not show."""
    from rigkit.capture import LaserReading, add_target, utc_now

    session = create_session(demo.capture / "strays", demo.rig)
    for position in ("left", "right", "back"):
        session = add_position_frame(session, position, demo.scene / f"{position}.png")
    readings = [LaserReading(r, utc_now(), "manual") for r in (200.5, 200.6, 230.0)]
    add_target(session, "T1", (200.0, 150.0), readings=readings)
    app = FieldApp(FieldConfig(capture=demo.capture, session=session.path, graphics=False))
    async with app.run_test(size=SIZE) as pilot:
        await opened(pilot, app)
        await wait_for(pilot, lambda: isinstance(app.screen, ProcessScreen)
                       and "not processed yet" in text(app, "#stage"), "processing")
        await pilot.press("r")  # reopened at processing, it waits to be asked
        await wait_for(pilot, lambda: "targets within" in text(app, "#verdict"), "the verdict",
                       60)
        verdict = text(app, "#verdict").replace("\n", " ")
        assert "T1: reading 3 (230.00 m) is far from the others" in verdict
        await pilot.press("q")


@synchronous
async def test_x_on_a_frame_asks_before_it_is_taken_out(demo: Demo) -> None:
    """Issue 37, item 8: `x` took a frame out at once; frames now ask, as targets do."""
    session, app = watching_app(demo)
    async with app.run_test(size=SIZE) as pilot:
        await opened(pilot, app)
        await take_the_left_frame(pilot, app, demo)
        await pilot.press("x")
        await pilot.pause()
        assert len(frames_at(load_session(session), "left")) == 1  # asked first
        await pilot.press("x")
        await wait_for(pilot, lambda: not frames_at(load_session(session), "left"),
                       "the frame taken out")
    assert (session / "raw" / "DSCN0001.PNG").is_file()  # its file stays
