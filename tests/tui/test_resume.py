"""Pilot tests of ``rigkit field`` reopened on a session (issue 37, item 4): it opens at
the step where the operator stopped, never runs processing by itself, and offers the
card's frames that the session does not hold."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

from rigkit.batch import new_run_id, process_session
from rigkit.capture import LaserReading, Session, Target, create_session, load_session
from rigkit.capture.field import add_position_frame, frames_at, resume_step
from rigkit.capture.positioning import set_field_step
from rigkit.capture.results import RESULTS_DIR
from rigkit.capture.session import save_session
from rigkit.synth.demo import Demo
from rigkit.tui.app import FieldApp
from rigkit.tui.config import FieldConfig
from rigkit.tui.screens import PositionScreen, ProcessScreen
from tests.tui.conftest import SETTLE_S, opened, synchronous, text, wait_for, write_frame
from tests.tui.test_flow import SIZE, take_position

READING = LaserReading(slope_distance_m=200.0, time_utc="2026-11-26T10:00:00Z",
                       source="manual")


def framed(demo: Demo, name: str, reading: bool = True) -> Session:
    """A session with the demo's three frames and, with ``reading``, a target with a
    reading: one the capture order alone would send to processing."""
    session = create_session(demo.capture / name, demo.rig)
    for position in ("left", "right", "back"):
        session = add_position_frame(session, position, demo.scene / f"{position}.png")
    if reading:
        target = Target(name="T1", pixel=(190.0, 140.0), window_px=9, readings=(READING,))
        save_session(replace(load_session(session.path), targets=(target,)))
    return load_session(session.path)


def app_on(demo: Demo, session: Path, watch: Path | None = None) -> FieldApp:
    return FieldApp(FieldConfig(capture=demo.capture, session=session, watch=watch,
                                graphics=False, settle_s=SETTLE_S))


def app_at(demo: Demo, name: str, step: str, reading: bool = True
           ) -> tuple[Session, FieldApp]:
    """A :func:`framed` session left at ``step``, and the app that will open it."""
    session = set_field_step(framed(demo, name, reading).path, step)
    return session, app_on(demo, session.path)


@synchronous
async def test_quit_while_retaking_the_right_burst_reopens_at_right(demo: Demo) -> None:
    """Before: a session whose positions all had frames and a target a reading reopened
    straight into processing, whatever step the operator had quit on."""
    session, app = app_at(demo, "retaking", "right")
    async with app.run_test(size=SIZE) as pilot:
        await opened(pilot, app)
        assert "parallax" in await take_position(pilot, app, "right")
        await pilot.press("n")
        await wait_for(pilot, lambda: app.screen.position == "back", "the back screen")
        await pilot.press("q")
    assert load_session(session.path).field_step == "back"  # where the next launch opens
    assert not (session.path / RESULTS_DIR).exists()  # nothing was processed


@synchronous
async def test_reopened_at_processing_it_waits_to_be_asked(demo: Demo) -> None:
    session, app = app_at(demo, "at-process", "process")
    async with app.run_test(size=SIZE) as pilot:
        await opened(pilot, app)
        await wait_for(pilot, lambda: isinstance(app.screen, ProcessScreen), "processing")
        await pilot.pause(0.3)
        assert "not processed yet; r: process" in text(app, "#stage")
    assert not (session.path / RESULTS_DIR).exists()


@synchronous
async def test_reopened_it_shows_no_run_that_no_longer_shows_the_session(demo: Demo) -> None:
    """The latest run is shown while frames and targets are as it had them; once a
    target is added it is not (its table and verdict would be another capture's), and
    the screen says why."""
    session = framed(demo, "reopened")
    set_field_step(session.path, "process")
    process_session(session.path, new_run_id())
    app = app_on(demo, session.path)
    async with app.run_test(size=SIZE) as pilot:
        await opened(pilot, app)
        await wait_for(pilot, lambda: "latest run shown" in text(app, "#stage"), "the run")
        assert "targets within" in text(app, "#verdict")
    late = Target(name="T2", pixel=(100.0, 100.0), window_px=9, readings=(READING,))
    save_session(replace(load_session(session.path),
                         targets=(*load_session(session.path).targets, late)))
    app = app_on(demo, session.path)
    async with app.run_test(size=SIZE) as pilot:
        await opened(pilot, app)
        await wait_for(pilot, lambda: "before the targets changed" in text(app, "#stage"),
                       "why the run is not shown")
        assert "process again" in text(app, "#stage") and text(app, "#verdict").strip() == ""
    save_session(replace(load_session(session.path),  # as the run had them again
                         targets=load_session(session.path).targets[:1]))
    (session.path / RESULTS_DIR / "comparisons.csv").write_text("garbage,,,\n")
    app = app_on(demo, session.path)
    async with app.run_test(size=SIZE) as pilot:  # a damaged results/ is said, no crash
        await opened(pilot, app)
        await wait_for(pilot, lambda: "comparisons.csv is unreadable" in text(app, "#stage"),
                       "the damaged results said")
        assert app.is_running and text(app, "#verdict").strip() == ""
    record = session.path / RESULTS_DIR / "depth.json"  # hostile numbers in the record
    record.write_text(record.read_text().replace('"offset_depth_error_fraction": ',
                                                 '"offset_depth_error_fraction": 1e200, "_": '))
    app = app_on(demo, session.path)
    async with app.run_test(size=SIZE) as pilot:  # before: the TUI ended on opening
        await opened(pilot, app)
        await wait_for(pilot, lambda: "offset_depth_error_fraction" in text(app, "#stage"),
                       "the refused record said")
        assert "1e+200" in text(app, "#stage") and app.is_running


@synchronous
async def test_a_verdict_longer_than_its_box_scrolls_rather_than_hides(demo: Demo) -> None:
    """Before: the verdict box clipped at 6 lines, and the warnings, written last (a
    reading far from the others: a typo?), were the lines an 80x24 screen never showed."""
    session = framed(demo, "long-verdict")
    typo = replace(READING, slope_distance_m=2000.0)
    targets = tuple(Target(name=f"T{i}", pixel=(60.0 + 40 * i, 140.0), window_px=9,
                           readings=(READING, READING, typo)) for i in range(1, 5))
    save_session(replace(load_session(session.path), targets=targets))
    set_field_step(session.path, "process")
    process_session(session.path, new_run_id())
    app = app_on(demo, session.path)
    async with app.run_test(size=SIZE) as pilot:
        await opened(pilot, app)
        await wait_for(pilot, lambda: "latest run shown" in text(app, "#stage"), "the run")
        assert text(app, "#verdict").count("is far from the others") == 4
        box = app.screen.query_one("#verdict-box")
        assert box.max_scroll_y > 0  # the rest is a scroll away, with a scrollbar


        def at_the_end() -> bool:  # the layout may settle after the first frame drawn
            box.scroll_end(animate=False)
            return box.max_scroll_y > 0 and box.scroll_y == box.max_scroll_y

        await wait_for(pilot, at_the_end, "the verdict's last line", 5)


def test_resume_step_never_opens_a_step_whose_frames_are_missing(demo: Demo) -> None:
    session = create_session(demo.capture / "bare", demo.rig)
    assert resume_step(session) == "rig"  # never opened, nothing taken
    session = add_position_frame(session, "left", demo.scene / "left.png")
    assert resume_step(session) == "right"
    for step, expected in (("left", "left"), ("targets", "right"), ("process", "right")):
        assert resume_step(set_field_step(session.path, step)) == expected


@synchronous
async def test_frames_left_on_the_card_are_offered_again(demo: Demo) -> None:
    """Before: a frame that reached the card while the app was closed, or one left there
    with Esc, was never offered again and nothing said so."""
    session = create_session(demo.capture / "card", demo.rig)
    write_frame(demo.card / "DSCN0001.PNG", demo.scene / "left.png")  # while closed
    app = app_on(demo, session.path, watch=demo.card)
    async with app.run_test(size=SIZE) as pilot:
        await opened(pilot, app)
        await pilot.press("n")
        await wait_for(pilot, lambda: isinstance(app.screen, PositionScreen)
                       and "DSCN0001.PNG" in text(app, "#card"), "the card's frame offered")
        assert "on the card, not in the session: DSCN0001.PNG" in text(app, "#card")
        await pilot.press("c")
        assert "✘" not in await take_position(pilot, app, "left")
        await wait_for(pilot, lambda: not app.screen.query_one("#card").display,
                       "the offer gone")
    assert [Path(f.file).name for f in frames_at(load_session(session.path), "left")] == \
        ["DSCN0001.PNG"]


def test_the_card_listing_counts_only_real_files_in_raw_and_survives_a_bad_date(
        demo: Demo) -> None:
    from rigkit.tui.watch import unfiled

    session = create_session(demo.capture / "links", demo.rig)
    card = write_frame(demo.card / "DSCN0009.PNG", demo.scene / "left.png")
    (session.path / "raw").mkdir(exist_ok=True)
    (session.path / "raw" / card.name).symlink_to(card)  # a link is not a frame held
    assert unfiled(demo.card, session) == [card]
    assert unfiled(demo.card, replace(session, created_utc="not a date")) == [card]
