"""Snapshots of the main screens at 80x24 (pytest-textual-snapshot; update them with
``pytest tests/tui --snapshot-update`` and look at the SVGs before committing).

The frames are a drawn test card, not a rendered scene, and the results screen reads a
prepared run, so the snapshots do not change when the renderer or the pipeline does.
"""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import pytest

from rigkit.capture import LaserReading, add_target, create_session, load_session
from rigkit.capture.comparisons import LOG_NAME, STATUS_OK, Comparison, append_rows
from rigkit.capture.field import add_position_frame
from rigkit.tui.app import FieldApp
from rigkit.tui.config import FieldConfig
from rigkit.tui.screens import PositionScreen, TargetsScreen
from rigkit.tui.widgets import PixelView
from tests.conftest import make_record, rig_file
from tests.tui.conftest import opened, side, text, wait_for

ROOT = Path(__file__).resolve().parents[2]
P1000 = ROOT / "rigs" / "p1000-tripod.yaml"
SIZE = (80, 24)


def drawn_card(shift: int = 0) -> np.ndarray:
    """(384, 512) uint8: sky gradient, a ridge, rings and blocks; ``shift`` moves it."""
    v, u = np.mgrid[0:384, 0:512].astype(np.float32)
    image = 200 - 0.3 * v
    ridge = 150 + 30 * np.sin((u + shift) / 50)
    image = np.where(v > ridge, 90 + 40 * np.sin((u + shift) / 7) * np.sin(v / 9), image)
    rings = np.hypot(u + shift - 300, v - 260)
    image = np.where(rings < 60, 128 + 100 * np.sin(rings / 4), image)
    image[300:340, 60 - shift // 2:120 - shift // 2] = 240
    return np.clip(image, 0, 255).astype(np.uint8)


def session_with_frames(folder: Path, positions: tuple[str, ...]) -> Path:
    session = create_session(folder, rig_file(folder.parent, (512, 384), "p1000-tripod.yaml",
                                              "p1000-512.yaml"))
    for i, position in enumerate(positions):
        path = folder.parent / f"{position}.png"
        cv2.imwrite(str(path), drawn_card(shift=8 * i))
        session = add_position_frame(session, position, path)
    return session.path


@pytest.fixture
def capture(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    """A relative capture folder, so no temporary path shows on screen."""
    monkeypatch.chdir(tmp_path)
    (tmp_path / "capture").mkdir()
    return Path("capture")


def app_for(capture: Path, session: Path | None = None) -> FieldApp:
    return FieldApp(FieldConfig(capture=capture, session=session, graphics=False))


def test_start_screen_lists_sessions(snap_compare, capture: Path) -> None:
    session_with_frames(capture / "ridge-0412", ("left", "right"))
    create_session(capture / "ridge-0413", P1000)
    app = app_for(capture)
    assert snap_compare(app, terminal_size=SIZE, run_before=lambda pilot: opened(pilot, app))


def test_rig_screen(snap_compare, capture: Path) -> None:
    create_session(capture / "ridge", P1000)
    app = app_for(capture, capture / "ridge")
    assert snap_compare(app, terminal_size=SIZE, run_before=lambda pilot: opened(pilot, app))


def test_left_position_with_a_checked_frame(snap_compare, capture: Path) -> None:
    app = app_for(capture, session_with_frames(capture / "ridge", ("left",)))

    async def back_to_left(pilot) -> None:
        await opened(pilot, app)
        await pilot.press("b")
        await wait_for(pilot, lambda: isinstance(app.screen, PositionScreen)
                       and "✔" in side(app), "the left frame's checks")

    assert snap_compare(app, terminal_size=SIZE, run_before=back_to_left)


def test_targets_screen_with_marks_and_zoom(snap_compare, capture: Path) -> None:
    path = session_with_frames(capture / "ridge", ("left", "right", "back"))
    add_target(load_session(path), "T1", (300.0, 260.0))  # marked, not yet fired at
    app = app_for(capture, path)

    async def aim(pilot) -> None:
        await wait_for(pilot, lambda: isinstance(app.screen, TargetsScreen)
                       and app.screen.query_one(PixelView).cursor is not None, "the left view")
        await pilot.press("left", "left", "up", "plus", "up")

    assert snap_compare(app, terminal_size=SIZE, run_before=aim)


def _row(target: str, laser: float, error_pct: float) -> Comparison:
    estimate = laser * (1 + error_pct / 100)
    return Comparison(
        run_id="20260412T081500Z-0001", time_utc="2026-04-12T08:15:00Z", session="ridge",
        target=target, u=300.0, v=260.0, window_px=9, laser_range_m=laser, laser_readings=2,
        laser_spread_m=0.1, estimate_range_m=estimate, estimate_sigma_m=2.0,
        valid_fraction=1.0, error_m=estimate - laser, error_pct=error_pct, status=STATUS_OK,
    )


def test_results_of_a_run(snap_compare, capture: Path) -> None:
    path = session_with_frames(capture / "ridge", ("left", "right", "back"))
    session = load_session(path)
    for name, (u, v) in (("T1", (300.0, 260.0)), ("T2", (100.0, 320.0))):
        session = add_target(session, name, (u, v),
                             readings=[LaserReading(300.0, "2026-04-12T08:01:12Z", "manual")])
    (path / "results").mkdir()
    np.save(path / "results" / "depth.npy", 250.0 + drawn_card().astype(np.float32) / 2.5)
    record = make_record(session, median_depth_m=None)  # no scale line
    (path / "results" / "depth.json").write_text(record.to_json())
    append_rows(path / LOG_NAME, [_row("T1", 301.2, 0.8), _row("T2", 288.0, -4.6)])
    app = app_for(capture, path)

    async def shown_run(pilot) -> None:
        # The run is read off the screen's thread; the table sizes its columns to the
        # rows once the app is idle: under load the picture was taken in between.
        await wait_for(pilot, lambda: app.screen.query("#stage")
                       and "latest run shown" in text(app, "#stage"), "the run")
        await pilot.pause()

    assert snap_compare(app, terminal_size=SIZE, run_before=shown_run)
