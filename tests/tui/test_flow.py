"""Pilot tests of ``rigkit field``: the demo flow from frames to the verdict, checks that
fail as they should, typed ranges, and quitting mid-flow then resuming."""

from __future__ import annotations

import hashlib
import shutil
from pathlib import Path

from rigkit.capture import POSITIONS, Session, create_session, load_session, read_rows
from rigkit.capture.field import add_position_frame, frames_at
from rigkit.synth.demo import Demo
from rigkit.tui.app import FieldApp
from rigkit.tui.config import FieldConfig
from rigkit.tui.screens import PositionScreen, ProcessScreen, RigScreen, TargetsScreen
from rigkit.tui.widgets import PixelView
from tests.tui.conftest import SETTLE_S, synchronous, text, wait_for, write_frame

SIZE = (80, 24)


def taken(session: Session) -> list[str]:
    """The positions that have a frame."""
    return [p for p in POSITIONS if frames_at(session, p)]


def demo_app(demo: Demo) -> FieldApp:
    return FieldApp(FieldConfig(capture=demo.capture, session=demo.session,
                                demo=demo, graphics=False, settle_s=SETTLE_S))


async def take_position(pilot, app: FieldApp, position: str) -> str:
    """Wait on ``position``'s screen until its frame is checked; return the checks text."""
    await wait_for(pilot, lambda: isinstance(app.screen, PositionScreen)
                   and app.screen.position == position, f"the {position} screen")
    await wait_for(pilot, lambda: "✔" in text(app, "#checks") or "✘" in text(app, "#checks"),
                   f"the {position} frame's checks")
    return text(app, "#checks")


async def mark_target(pilot, app: FieldApp, moves: list[str], readings: int) -> None:
    await pilot.press(*moves, "enter")
    count = len(app.session.targets)  # type: ignore[union-attr]
    await wait_for(pilot, lambda: len(app.session.targets[count - 1].readings) >= readings,
                   f"{readings} readings of T{count}")


@synchronous
async def test_demo_flow_from_frames_to_verdict(demo: Demo) -> None:
    app = demo_app(demo)
    async with app.run_test(size=SIZE) as pilot:
        assert isinstance(app.screen, RigScreen)
        assert "focal length" in text(app, "#rig")
        await pilot.press("n")
        assert "no EXIF" in await take_position(pilot, app, "left")
        await pilot.press("n")
        right = await take_position(pilot, app, "right")
        assert "✘" not in right and "parallax" in right
        await pilot.press("n")
        back = await take_position(pilot, app, "back")
        assert "✘" not in back and "× → ~" in back and "at C_lb = 2.0 m" in back
        await pilot.press("n")
        await wait_for(pilot, lambda: isinstance(app.screen, TargetsScreen)
                       and app.screen.query_one(PixelView).cursor is not None, "the left view")
        await mark_target(pilot, app, ["right", "right", "down"], 3)
        await mark_target(pilot, app, ["left"] * 6 + ["up"] * 4, 3)
        assert "T2" in text(app, "#targets") and "-> T2" in text(app, "#readings")
        await pilot.press("n")
        await wait_for(pilot, lambda: isinstance(app.screen, ProcessScreen)
                       and "targets within" in text(app, "#verdict"), "the verdict", 60)
        assert app.screen.query_one("#rows").row_count == 2
        await pilot.press("e")  # export: no tripod position, so in the camera frame
        await wait_for(pilot, lambda: "points in the camera frame" in text(app, "#stage"),
                       "the export", 30)
        await pilot.press("q")
    assert sorted(p.name for p in (demo.session / "export").iterdir()) == [
        f"{demo.session.name}.las", f"{demo.session.name}.ply"]
    session = load_session(demo.session)
    assert taken(session) == ["left", "right", "back"]
    assert [len(t.readings) for t in session.targets] == [3, 3]
    assert all(r.source.startswith("trupulse:sim://") for r in session.targets[0].readings)
    assert (demo.session / "results" / "depth.npy").is_file()
    for number, position in enumerate(("left", "right", "back"), 100):  # originals untouched
        card = (demo.card / f"DSCN{number:04d}.PNG").read_bytes()
        assert card == (demo.scene / f"{position}.png").read_bytes()
        assert hashlib.sha256(card).hexdigest() == frames_at(session, position)[-1].sha256


@synchronous
async def test_checks_catch_a_duplicate_frame_and_an_exif_mismatch(demo: Demo) -> None:
    session = create_session(demo.capture / "field-1", demo.rig).path
    app = FieldApp(FieldConfig(capture=demo.capture, session=session,
                               watch=demo.card, graphics=False, settle_s=SETTLE_S))
    async with app.run_test(size=SIZE) as pilot:
        await pilot.press("n")
        await wait_for(pilot, lambda: isinstance(app.screen, PositionScreen), "the left screen")
        write_frame(demo.card / "DSCN0001.PNG", demo.scene / "left.png", iso=100)
        assert "EXIF agrees" in await take_position(pilot, app, "left")
        await pilot.press("n")
        await wait_for(pilot, lambda: app.screen.position == "right", "the right screen")
        shutil.copy(demo.card / "DSCN0001.PNG", demo.card / "DSCN0002.PNG")
        checks = await take_position(pilot, app, "right")
        assert "DSCN0002.PNG is the same file as raw/DSCN0001.PNG, given for left and right" in \
            checks.replace("\n", " ")
        assert not frames_at(load_session(session), "right")  # refused on arrival
        write_frame(demo.card / "DSCN0003.PNG", demo.scene / "right.png", iso=400)
        await wait_for(pilot, lambda: "DSCN0003" in text(app, "#checks") and "✘" in
                       text(app, "#checks"), "the EXIF mismatch")
        checks = text(app, "#checks")
        assert "ISO 400 differs from the left frame's ISO 100" in checks and "redo:" in checks
        write_frame(demo.card / "DSCN0004.PNG", demo.scene / "right.png", iso=100)
        await wait_for(pilot, lambda: "DSCN0004" in text(app, "#checks") and "parallax" in
                       text(app, "#checks"), "the good right frame")
        assert "✘" not in text(app, "#checks")
    recorded = load_session(session)
    assert frames_at(recorded, "right")[-1].file == "raw/DSCN0004.PNG"
    # The refused copy never entered raw/; the frame that failed its check is kept.
    assert sorted(p.name for p in (session / "raw").iterdir()) == \
        ["DSCN0001.PNG", "DSCN0003.PNG", "DSCN0004.PNG"]


@synchronous
async def test_quit_mid_flow_resumes_where_it_stopped(demo: Demo) -> None:
    app = demo_app(demo)
    async with app.run_test(size=SIZE) as pilot:
        await pilot.press("n")
        await take_position(pilot, app, "left")
        await pilot.press("n")
        await take_position(pilot, app, "right")
        await pilot.press("q")
    assert taken(load_session(demo.session)) == ["left", "right"]
    app = demo_app(demo)
    async with app.run_test(size=SIZE) as pilot:
        assert "✘" not in await take_position(pilot, app, "back")  # straight to the back
        await pilot.press("b")
        assert "parallax" in await take_position(pilot, app, "right")  # checked again
    assert taken(load_session(demo.session)) == ["left", "right", "back"]


@synchronous
async def test_typed_ranges_and_a_verdict_that_asks_for_more(demo: Demo) -> None:
    session = create_session(demo.capture / "typed", demo.rig)
    for position in ("left", "right", "back"):
        session = add_position_frame(session, position, demo.scene / f"{position}.png")
    app = FieldApp(FieldConfig(capture=demo.capture, session=session.path, graphics=False))
    async with app.run_test(size=SIZE) as pilot:
        await wait_for(pilot, lambda: isinstance(app.screen, TargetsScreen)
                       and app.screen.query_one(PixelView).cursor is not None, "the left view")
        assert "no rangefinder port" in text(app, "#link")
        await pilot.press("m", *"301.5", "enter")
        assert "not kept: mark a target first" in text(app, "#readings")
        await pilot.press("enter", "m", *"abc", "enter", "q")  # T1 marked, no reading
    assert [t.name for t in load_session(session.path).targets] == ["T1"]
    app = FieldApp(FieldConfig(capture=demo.capture, session=session.path, graphics=False))
    async with app.run_test(size=SIZE) as pilot:
        await wait_for(pilot, lambda: isinstance(app.screen, TargetsScreen)
                       and "T1" in text(app, "#targets"), "the targets, resumed")
        await pilot.press("m", *"250", "enter")  # far from the true ~300 m
        assert [r.slope_distance_m for r in app.session.targets[0].readings] == [250.0]
        assert app.session.targets[0].readings[0].source == "manual"
        await pilot.press("n")
        await wait_for(pilot, lambda: "targets within" in text(app, "#verdict"), "the verdict",
                       60)
        verdict = text(app, "#verdict")
        assert "0/1 targets within" in verdict and "capture again" in verdict
        assert "T1: off by +" in verdict
        await pilot.press("b", "m", *"300", "enter", "n")  # one more reading: run again
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
        await pilot.press("tab", *"ridge-9 nowhere.yaml", "enter")
        assert "nowhere.yaml" in text(app, "#message")
        assert not (demo.capture / "ridge-9").exists()
        app.screen.query_one("#new").value = ""
        await pilot.press(*f"ridge-9 {demo.rig}", "enter")
        await wait_for(pilot, lambda: isinstance(app.screen, RigScreen), "the new session's rig")
    assert load_session(demo.capture / "ridge-9").rig().name.startswith("synthetic")
    app = FieldApp(FieldConfig(capture=demo.capture, graphics=False))
    async with app.run_test(size=SIZE) as pilot:
        table = app.screen.query_one("#sessions")
        assert table.row_count == 2  # demo and ridge-9, sorted by name
        await pilot.press("down", "enter")
        await wait_for(pilot, lambda: isinstance(app.screen, RigScreen), "ridge-9 opened")
        assert app.session is not None and app.session.name == "ridge-9"
