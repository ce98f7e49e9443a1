"""The field TUI's screens, one per step: start (sessions), rig, left/right/back
positions, laser targets, processing. Each screen shows what the library computes and
changes the session only through :mod:`rigkit.capture`."""

from __future__ import annotations

import math
from pathlib import Path
from typing import TYPE_CHECKING, Any

import cv2
import numpy as np
from textual import work
from textual.app import ComposeResult
from textual.binding import Binding
from textual.containers import Horizontal, Vertical, VerticalScroll
from textual.screen import Screen
from textual.widgets import DataTable, Footer, Header, Input, ProgressBar, Static
from textual.worker import get_current_worker

from rigkit.batch import new_run_id, process_session
from rigkit.capture import (
    RESULTS_DIR,
    LaserReading,
    Session,
    Target,
    add_target,
    create_session,
    is_session,
    load_session,
    read_rows,
    utc_now,
)
from rigkit.capture.comparisons import Comparison, latest_run
from rigkit.capture.field import check_image, frames_at, next_step, reading_from_device
from rigkit.errors import RigkitError
from rigkit.rangefinder.follow import LinkStatus, follow
from rigkit.reporting.verdict import judge, offset_note
from rigkit.rig.budget import budget_row
from rigkit.rig.check import check_rig
from rigkit.rig.findings import Finding
from rigkit.rig.optics import fov_deg
from rigkit.tui.previews import preview_widget
from rigkit.tui.widgets import Mark, PixelView

if TYPE_CHECKING:
    from rigkit.tui.app import FieldApp

PLANNED_RANGE_M = 300.0
"""Range the rig summary is given at when the profile names none (as `rigkit rig check`)."""

CHECKLISTS = {
    "left": (
        "camera in manual mode (M), fixed ISO, fixed white balance",
        "zoom set and noted; focus locked (MF)",
        "vibration reduction off (on a tripod)",
        "RAW (NRW) on; self-timer or remote release",
        "burst of several frames: shimmer averages out",
    ),
    "right": (
        "tripod moved C_lr to the right, same height",
        "same zoom, focus, ISO and exposure as the left frame",
        "aim at the same scene; keep the camera level",
    ),
    "back": (
        "tripod moved C_lb straight back from the LEFT position",
        "C_lb measured with the tape: {c_lb}",
        "same zoom, focus, ISO and exposure as before",
    ),
}


def field_app(screen: Screen[Any]) -> FieldApp:
    """The running FieldApp (typed)."""
    return screen.app  # type: ignore[return-value]


def session_of(screen: Screen[Any]) -> Session:
    session = field_app(screen).session
    assert session is not None, "a step screen needs an open session"
    return session


def check_lines(checks: list[Finding]) -> str:
    """Checks as Rich markup: a tick or a cross, the message, and what to redo."""
    lines = []
    for check in checks:
        mark = "[b $success]✔[/]" if check.ok else "[b $error]✘[/]"
        lines.append(f"{mark} {_escape(check.message)}")
        if check.redo:
            lines.append(f"  [b $warning]redo:[/] {_escape(check.redo)}")
    return "\n".join(lines)


def _escape(text: str) -> str:
    return text.replace("[", r"\[")


class StepScreen(Screen[None]):
    """A step of the flow: header, footer with key hints, ``n``/``b`` to move on/back."""

    step = ""
    BINDINGS = [
        Binding("n", "next", "next step"),
        Binding("b", "back", "back"),
    ]

    def action_next(self) -> None:
        after = field_app(self).step_after(self.step, +1)
        if after is not None:
            field_app(self).goto(after)

    def action_back(self) -> None:
        before = field_app(self).step_after(self.step, -1)
        if before is not None:
            field_app(self).goto(before)


# -- start: the sessions in the capture folder, or a new one ---------------------------------


class StartScreen(Screen[None]):
    """Resume a session of the capture folder, or start a new one with a rig profile."""

    AUTO_FOCUS = "#sessions"
    BINDINGS = [Binding("enter", "open", "open session", show=True)]

    def compose(self) -> ComposeResult:
        yield Header()
        yield Static("Sessions in " + str(field_app(self).config.capture), classes="title")
        yield DataTable(id="sessions", cursor_type="row")
        yield Static("Enter: open the selected session   Tab: start a new one below",
                     id="hint")
        yield Static("New session: NAME RIG.yaml, then Enter", classes="title")
        yield Input(placeholder="ridge-0412 rigs/p1000-tripod.yaml", id="new")
        yield Static("", id="message")
        yield Footer()

    def on_mount(self) -> None:
        table = self.query_one(DataTable)
        table.add_columns("session", "next step", "frames", "targets")
        capture = field_app(self).config.capture
        folders = sorted(p for p in capture.iterdir() if is_session(p)) if capture.is_dir() else []
        for folder in folders:
            try:
                session = load_session(folder)
            except RigkitError:  # opening it shows why
                table.add_row(folder.name, "unreadable", "", "", key=str(folder))
                continue
            frames = sum(len(frames_at(session, p)) for p in ("left", "right", "back"))
            table.add_row(session.name, next_step(session), str(frames),
                          str(len(session.targets)), key=str(folder))

    def key_escape(self) -> None:
        """Leave the new-session box: keys (q included) go to the list again."""
        self.query_one(DataTable).focus()

    def action_open(self) -> None:
        table = self.query_one(DataTable)
        if table.row_count == 0:
            return
        key = table.coordinate_to_cell_key(table.cursor_coordinate).row_key.value
        self._open(Path(str(key)))

    def on_data_table_row_selected(self, event: DataTable.RowSelected) -> None:
        self._open(Path(str(event.row_key.value)))

    def _open(self, folder: Path) -> None:
        try:
            field_app(self).open_session(load_session(folder))
        except RigkitError as exc:
            self.query_one("#message", Static).update(f"[b $error]{_escape(str(exc))}[/]")

    def on_input_submitted(self, event: Input.Submitted) -> None:
        parts = event.value.split()
        app = field_app(self)
        rig = Path(parts[1]) if len(parts) > 1 else app.config.rig
        if not parts or rig is None:
            self.query_one("#message", Static).update(
                "[b $error]give a session name and a rig profile (NAME RIG.yaml)[/]")
            return
        try:
            session = create_session(app.config.capture / parts[0], rig)
        except RigkitError as exc:
            self.query_one("#message", Static).update(f"[b $error]{_escape(str(exc))}[/]")
            return
        app.open_session(session)


# -- the rig ------------------------------------------------------------------------------


class RigScreen(StepScreen):
    """The rig check's summary: focal length, FOV, precision at the planned range."""

    step = "rig"

    def compose(self) -> ComposeResult:
        yield Header()
        with VerticalScroll():  # many warnings scroll (arrows, page keys) at 80x24
            yield Static(self._summary(), id="rig")
        yield Footer()

    def on_mount(self) -> None:
        self.query_one(VerticalScroll).focus()

    def _summary(self) -> str:
        profile = session_of(self).rig()
        nominal = profile.nominal_range_m or PLANNED_RANGE_M
        check = check_rig(profile, [nominal])
        width, height = profile.image_size
        focal = profile.focal_px
        row = budget_row(check.model, nominal)
        lines = [
            f"[b]rig {profile.name}[/]  {width} x {height} px",
            f"focal length   {focal:,.0f} px ± {100 * profile.focal_tolerance:g} %",
            f"field of view  {fov_deg(focal, width):.2f} x {fov_deg(focal, height):.2f} deg",
            f"baselines      C_lr {profile.baseline_lr.value_m:g} m, "
            f"C_lb {profile.baseline_lb.value_m:g} m",
            f"{f'at {nominal:g} m':<14} disparity {row.disparity_px:.1f} px, depth error "
            f"± {row.total_m:.1f} m ({100 * row.total_fraction:.1f} %)",
            "",
        ]
        if check.findings:
            lines.append(f"[b $warning]warnings ({len(check.findings)}):[/]")
            lines += [f"- {_escape(f.message)}" for f in check.findings]
        else:
            lines.append("[b $success]no warnings[/]")
        lines += ["", "Press [b]n[/] to start with the left position."]
        return "\n".join(lines)


# -- a camera position ----------------------------------------------------------------------


class PositionScreen(StepScreen):
    """One camera position: its checklist, the frames as they arrive, their checks."""

    BINDINGS = [Binding("o", "open_file", "add file")]

    def __init__(self, position: str) -> None:
        super().__init__()
        self.position = position
        self.step = position
        self._shown = ""  # the newest frame's checks, as markup

    def compose(self) -> ComposeResult:
        yield Header()
        with Horizontal():
            with Vertical(id="side"):
                yield Static(self._checklist(), id="checklist")
                yield Static(self._waiting(), id="checks")
            yield Vertical(id="preview")
        yield Input(placeholder="path of a frame file, then Enter (Esc: cancel)", id="path")
        yield Footer()

    def _checklist(self) -> str:
        c_lb = f"{session_of(self).rig().baseline_lb.value_m:g} m in the profile"
        items = [item.format(c_lb=c_lb) for item in CHECKLISTS[self.position]]
        return f"[b]{self.position.upper()} position[/]\n" + "\n".join(f"• {i}" for i in items)

    def _waiting(self) -> str:
        app = field_app(self)
        folder = app.config.demo.card if app.config.demo else app.config.watch
        source = f"watching {folder}" if folder else "no folder watched"
        return f"{source}\nwaiting for the {self.position} frame (o: add a file)"

    def on_mount(self) -> None:
        self.query_one("#path", Input).display = False
        session = session_of(self)
        app = field_app(self)
        if frames_at(session, self.position):
            self.show_added(Path(frames_at(session, self.position)[-1].file).name)
            self._recheck(session)
        elif app.config.demo is not None:
            self._demo_shoot()

    @work(thread=True, group="check")
    def _recheck(self, session: Session) -> None:
        field_app(self).check_position(session, self.position)

    @work(thread=True, group="demo")
    def _demo_shoot(self) -> None:
        demo = field_app(self).config.demo
        assert demo is not None
        number = 100 + ("left", "right", "back").index(self.position)
        demo.shoot(self.position, number)

    def show_added(self, name: str) -> None:
        self.query_one("#checks", Static).update(f"frame {name}: checking ...")

    def show_error(self, message: str) -> None:
        """A file that could not be added or checked; the position keeps what it had."""
        self.query_one("#checks", Static).update(
            f"[b $error]✘ {_escape(message)}[/]\n{self._shown}")

    def show_checks(self, checks: list[Finding], image: np.ndarray) -> None:
        """The newest frame's checks, and its preview."""
        frames = frames_at(session_of(self), self.position)
        burst = f" ({len(frames)} frames)" if len(frames) > 1 else ""
        hint = "\n[b]n[/]: next step" if all(c.ok for c in checks) else ""
        self._shown = f"frame {Path(frames[-1].file).name}{burst}\n{check_lines(checks)}{hint}"
        self.query_one("#checks", Static).update(self._shown)
        preview = self.query_one("#preview", Vertical)
        preview.remove_children()
        preview.mount(preview_widget(image, field_app(self).config.graphics))

    def action_open_file(self) -> None:
        entry = self.query_one("#path", Input)
        entry.display = True
        entry.focus()

    def on_input_submitted(self, event: Input.Submitted) -> None:
        self.key_escape()
        if event.value.strip():
            field_app(self).ingest_file(Path(event.value.strip()).expanduser(), self.position)
        event.input.value = ""

    def key_escape(self) -> None:
        """Close the entry box; keys go to the screen again."""
        self.query_one("#path", Input).display = False
        self.set_focus(None)


# -- laser targets --------------------------------------------------------------------------


class TargetsScreen(StepScreen):
    """Mark where the laser hit on the left frame; readings arrive and are saved."""

    step = "targets"
    BINDINGS = [
        Binding("enter", "mark", "mark target"),
        Binding("plus,equals_sign", "zoom(1)", "zoom in", key_display="+"),
        Binding("minus", "zoom(-1)", "zoom out", key_display="-"),
        Binding("m", "manual", "type range"),
        Binding("up", "move(0, -1)", show=False),
        Binding("down", "move(0, 1)", show=False),
        Binding("left", "move(-1, 0)", show=False),
        Binding("right", "move(1, 0)", show=False),
        Binding("shift+up", "move(0, -8)", show=False),
        Binding("shift+down", "move(0, 8)", show=False),
        Binding("shift+left", "move(-8, 0)", show=False),
        Binding("shift+right", "move(8, 0)", show=False),
    ]
    DEMO_SHOTS = 3

    def __init__(self) -> None:
        super().__init__()
        self.reduction = 1.0  # full-resolution px per px of the shown left view
        self.protocol = "trupulse"
        self.readings: list[str] = []  # the newest first, as shown

    def compose(self) -> ComposeResult:
        yield Header()
        with Horizontal():
            yield PixelView(cursor=True, id="aim")
            with Vertical(id="side"):
                yield Static("", id="link")
                yield Static("", id="targets")
                yield Static("", id="readings")
        yield Input(placeholder="range in metres, then Enter (Esc: cancel)", id="range")
        yield Footer()

    def on_mount(self) -> None:
        self.query_one("#range", Input).display = False
        self._load_left()
        self._show_targets()
        app = field_app(self)
        port, self.protocol = app.config.port, app.config.protocol
        spec = session_of(self).rig().rangefinder
        if port is None and spec is not None and spec.port is not None:
            port, self.protocol = spec.port, spec.protocol
        if app.config.demo is None and port is not None:
            self._listen(port, 0)
        elif app.config.demo is None:
            self._link("no rangefinder port: type ranges with m")
        else:
            self._link("demo: mark a target (Enter), the simulated laser fires at it")

    @work(thread=True, group="aim")
    def _load_left(self) -> None:
        session = session_of(self)
        try:
            image, reduction = check_image(session, frames_at(session, "left")[-1])
        except RigkitError as exc:
            self.app.call_from_thread(self._link, str(exc))
            return
        self.reduction = reduction
        self.app.call_from_thread(self._show_left, image)

    def _show_left(self, image: np.ndarray) -> None:
        self.query_one(PixelView).set_image(image)
        self._show_targets()

    def _current(self) -> Target | None:
        """The newest target: readings go to it."""
        targets = session_of(self).targets
        return targets[-1] if targets else None

    def _show_targets(self) -> None:
        session = session_of(self)
        lines = ["[b]targets[/] (Enter marks one at the cursor)"]
        for target in session.targets:
            ranges = [r.slope_distance_m for r in target.readings]
            mean = f"{sum(ranges) / len(ranges):.2f} m" if ranges else "no reading"
            lines.append(f"{target.name} ({target.pixel[0]:.0f}, {target.pixel[1]:.0f}) "
                         f"{len(ranges)}x {mean}")
        view = self.query_one(PixelView)
        if view.cursor is not None:
            u, v = self._full(view.cursor)
            lines.append(f"cursor ({u:.0f}, {v:.0f})  zoom {view.zoom}x")
        self.query_one("#targets", Static).update("\n".join(lines))
        scale = self.reduction
        view.set_marks([Mark((t.pixel[0] + 0.5) / scale - 0.5, (t.pixel[1] + 0.5) / scale - 0.5,
                             t.name) for t in session.targets])

    def _full(self, cursor: tuple[int, int]) -> tuple[float, float]:
        """A check-image pixel in the full-resolution left frame (centres at integers)."""
        scale = self.reduction
        return (cursor[0] + 0.5) * scale - 0.5, (cursor[1] + 0.5) * scale - 0.5

    def action_move(self, du: int, dv: int) -> None:
        self.query_one(PixelView).move_cursor(du, dv)
        self._show_targets()

    def action_zoom(self, steps: int) -> None:
        self.query_one(PixelView).change_zoom(steps)
        self._show_targets()

    def action_mark(self) -> None:
        view = self.query_one(PixelView)
        if view.cursor is None:
            return
        session = session_of(self)
        taken = {t.name for t in session.targets}
        name = next(f"T{n}" for n in range(1, len(taken) + 2) if f"T{n}" not in taken)
        pixel = self._full(view.cursor)
        field_app(self).set_session(add_target(session, name, pixel))
        self._show_targets()
        demo = field_app(self).config.demo
        if demo is not None:
            self._listen(demo.laser_url(pixel), self.DEMO_SHOTS)

    def action_manual(self) -> None:
        entry = self.query_one("#range", Input)
        entry.display = True
        entry.focus()

    def key_escape(self) -> None:
        """Close the entry box; keys go to the screen again."""
        self.query_one("#range", Input).display = False
        self.set_focus(None)

    def on_input_submitted(self, event: Input.Submitted) -> None:
        self.key_escape()
        text, event.input.value = event.value.strip(), ""
        try:
            value = float(text)
        except ValueError:
            self.notify(f"{text!r}: not a range in metres", severity="error")
            return
        self._add_reading(LaserReading(value, utc_now(), "manual"))

    def _add_reading(self, reading: LaserReading) -> None:
        target = self._current()
        source = reading.source.split(":", 1)[0]
        self.readings.insert(
            0, f"{reading.time_utc[11:19]} {reading.slope_distance_m:8.2f} m {source}")
        del self.readings[6:]
        if target is None:
            self.readings[0] += "  (not kept: mark a target first)"
        else:
            try:
                session = add_target(session_of(self), target.name, target.pixel,
                                     window_px=target.window_px, readings=[reading])
            except RigkitError as exc:
                self.notify(str(exc), severity="error")
                return
            field_app(self).set_session(session)
            self.readings[0] += f"  -> {target.name}"
        self.query_one("#readings", Static).update("[b]readings[/]\n" + "\n".join(self.readings))
        self._show_targets()

    def _link(self, text: str) -> None:
        self.query_one("#link", Static).update(f"[b]laser[/] {_escape(text)}")

    @work(thread=True, exclusive=True, group="laser")
    def _listen(self, url: str, count: int) -> None:
        """Readings from ``url`` until the screen closes (or ``count`` of them, if > 0)."""
        worker = get_current_worker()
        app = field_app(self)
        protocol = self.protocol
        got = 0
        for item in follow(url, protocol, stopped=lambda: worker.is_cancelled or app.stop.is_set()):
            if isinstance(item, LinkStatus):
                app.call_from_thread(self._link, item.message)
                continue
            app.call_from_thread(self._add_reading,
                                 reading_from_device(item, f"{protocol}:{url}"))
            got += 1
            if count and got >= count:
                app.call_from_thread(self._link, f"{got} shots fired; mark the next target")
                return

    def on_unmount(self) -> None:
        self.workers.cancel_group(self, "laser")


# -- processing --------------------------------------------------------------------------


class Stopped(Exception):
    """Processing given up because its screen closed (raised from the progress report)."""


class ProcessScreen(StepScreen):
    """Run the depth pipeline; show the depth, the laser comparisons and the verdict."""

    step = "process"
    BINDINGS = [Binding("r", "run", "process")]

    def __init__(self, resume: bool = False) -> None:
        """``resume``: show the latest run if there is one, instead of processing."""
        super().__init__()
        self.resume = resume

    def compose(self) -> ComposeResult:
        yield Header()
        yield Static("", id="stage")
        yield ProgressBar(total=1.0, show_eta=False, id="progress")
        with Horizontal():
            yield Vertical(id="depth")
            yield DataTable(id="rows", cursor_type="none")
        yield Static("", id="verdict")
        yield Footer()

    def on_mount(self) -> None:
        table = self.query_one(DataTable)
        table.add_columns("target", "laser m", "depth m", "error", "ok")
        session = session_of(self)
        rows = latest_run(read_rows(session.path / "comparisons.csv")) \
            if (session.path / "comparisons.csv").is_file() else []
        if self.resume and rows and (session.path / RESULTS_DIR / "depth.png").is_file():
            self._show_results(rows)
            self.query_one("#stage", Static).update("latest run shown; r: process again")
        else:
            self.action_run()

    def action_run(self) -> None:
        self.query_one("#stage", Static).update("processing ...")
        self._process()

    @work(thread=True, exclusive=True, group="process")
    def _process(self) -> None:
        """Process the session; leaving the screen or quitting stops it at the next stage
        (nothing is written until a run is complete)."""
        app = field_app(self)
        path = session_of(self).path
        worker = get_current_worker()

        def progress(stage: str, fraction: float) -> None:
            if worker.is_cancelled:
                raise Stopped(stage)
            app.call_from_thread(self._progress, stage, fraction)

        try:
            outcome = process_session(path, new_run_id(), progress=progress)
        except Stopped:
            return
        except RigkitError as exc:
            app.call_from_thread(self._failed, str(exc))
            return
        app.call_from_thread(self._show_results, list(outcome.rows))

    def on_unmount(self) -> None:
        self.workers.cancel_group(self, "process")

    def _progress(self, stage: str, fraction: float) -> None:
        self.query_one("#stage", Static).update(f"{stage} {100 * fraction:.0f} %")
        self.query_one(ProgressBar).update(progress=fraction)

    def _failed(self, message: str) -> None:
        self.query_one("#stage", Static).update(f"[b $error]✘ {_escape(message)}[/]")

    def _show_results(self, rows: list[Comparison]) -> None:
        session = session_of(self)
        self.query_one(ProgressBar).update(progress=1.0)
        verdict = judge(rows, session.rig(), frames=session.burst_length)
        table = self.query_one(DataTable)
        table.clear()
        for row, target in zip(rows, verdict.targets, strict=True):
            error = "" if math.isnan(row.error_pct) else f"{row.error_pct:+.2f} %"
            table.add_row(row.target, _num(row.laser_range_m), _num(row.estimate_range_m),
                          error, "✔" if target.ok else "✘")
        colour = "$success" if verdict.ok else "$error"
        advice = "".join(f"\n- {_escape(a)}" for a in verdict.advice)
        note = offset_note(session.path)
        if note:
            advice += f"\n[$warning]{_escape(note)}[/]"
        self.query_one("#verdict", Static).update(
            f"[b {colour}]{_escape(verdict.headline)}[/]{advice}")
        depth = cv2.imread(str(session.path / RESULTS_DIR / "depth.png"), cv2.IMREAD_COLOR)
        box = self.query_one("#depth", Vertical)
        box.remove_children()
        if depth is not None:
            box.mount(PixelView(cv2.cvtColor(depth, cv2.COLOR_BGR2RGB)))


def _num(value: float) -> str:
    return "-" if math.isnan(value) else f"{value:.1f}"
