"""The process step: run the depth, show it with the laser comparisons and the verdict."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import cv2
import numpy as np
from rich.text import Text
from textual import work
from textual.app import ComposeResult
from textual.binding import Binding
from textual.containers import Horizontal, Vertical, VerticalScroll
from textual.timer import Timer
from textual.widgets import DataTable, Footer, ProgressBar, Static
from textual.worker import get_current_worker

from rigkit.batch import new_run_id, process_session
from rigkit.batch.session import stray_warnings
from rigkit.capture import Session, frame_problems, read_rows
from rigkit.capture.comparisons import LOG_NAME, Comparison, latest_run
from rigkit.capture.results import RunFiles, session_record, stale_results
from rigkit.errors import RigkitError, environment_message
from rigkit.imagefile.imagesize import MAX_FRAME_PIXELS
from rigkit.reporting.previews import colour_map, depth_range, scale_colours
from rigkit.reporting.verdict import Verdict, run_verdict
from rigkit.tui.header import FieldHeader
from rigkit.tui.screens.common import LaserLine, escape, host, session_of
from rigkit.tui.screens.exporting import ExportingScreen
from rigkit.tui.widgets import PixelView

START_AFTER_S = 0.4
"""Processing starts this long after the step opens, so that passing through it with
``n`` and ``b`` starts nothing."""


class Stopped(Exception):
    """Processing given up because its screen closed (raised from the progress report)."""


@dataclass(frozen=True)
class Shown:
    """A run as the screen shows it, computed off the screen's thread: the table's
    ``rows`` ((target, laser, depth, error, ok) texts), the verdict as markup, and the
    depth preview ((h, w, 3) uint8 RGB) with its colour bar's ends (m), None without."""

    rows: tuple[tuple[str, str, str, str, str], ...]
    verdict: str
    depth: np.ndarray | None
    lo: float
    hi: float


class ProcessScreen(ExportingScreen):
    """Run the depth pipeline; show the depth, the laser comparisons and the verdict;
    ``e`` exports the results (:mod:`rigkit.tui.screens.exporting`)."""

    step = "process"
    BINDINGS = [
        Binding("r", "run", "process"),
        Binding("down", "scroll(1)", "verdict", key_display="↑↓"),
        Binding("up", "scroll(-1)", show=False),
        Binding("pagedown", "scroll(5)", show=False),
        Binding("pageup", "scroll(-5)", show=False),
    ]

    def __init__(self, resume: bool = False) -> None:
        """``resume``: show the latest run if there is one, instead of processing."""
        super().__init__()
        self.resume = resume
        self._start: Timer | None = None  # processing about to start by itself
        self._busy = False  # a run started here and its outcome not yet on show

    def compose(self) -> ComposeResult:
        yield FieldHeader()
        with VerticalScroll(id="stage-box"):  # more than fits scrolls, never cut off
            yield Static("", id="stage")
        yield ProgressBar(total=1.0, show_eta=False, id="progress")
        with Horizontal(id="run"):
            yield Vertical(id="depth")
            yield DataTable(id="rows", cursor_type="none")
        with VerticalScroll(id="verdict-box"):  # grows with the terminal; ↑↓ scroll it
            yield Static("", id="verdict")
        yield LaserLine()
        yield Footer(compact=True)

    def on_mount(self) -> None:
        table = self.query_one(DataTable)
        table.add_columns("target", "laser m", "depth m", "error", "≤1 %")
        if not self.resume:
            self._stage("processing in a moment ...")
            self._start = self.set_timer(START_AFTER_S, self.action_run)  # stops if left
        else:  # reopened here: processing waits to be asked for
            self._stage("reading the latest run ...")
            self._resume()

    def running(self) -> bool:
        """Whether this screen's processing is under way: from ``r`` until its outcome is
        on show (set and cleared on the screen's thread, so a key pressed once the
        verdict shows never finds the run's worker still ending)."""
        return self._busy

    @work(thread=True, exclusive=True, group="resume")
    def _resume(self) -> None:
        """The latest run, shown only where it still shows the session: frames, rig and
        targets as the run had them, and every frame there (what ``session show`` says of
        it; the frames' hashes are read here, off the screen's thread)."""
        session = session_of(self)
        verdict = None
        try:  # a damaged log or results/ is said, and r processes again
            rows = latest_run(read_rows(session.path / LOG_NAME, [])) \
                if (session.path / LOG_NAME).is_file() else []
            done = bool(rows) and RunFiles.of_session(session.path).depth.is_file()
            why = (stale_results(session) or "; ".join(frame_problems(session))) if done else ""
            record = session_record(session.path) if done and not why else None
            if record is not None:  # the verdict rigkit process gave this run
                verdict = run_verdict(session, rows, session.rig(), record)
        except RigkitError as exc:
            done, why = True, str(exc)
        except OSError as exc:
            done, why = True, environment_message(exc)
        if not done:
            self.deliver(self._stage, "not processed yet; r: process")
        elif why or verdict is None:
            self.deliver(self._failed, f"{why or 'no results'}; r: process again")
        else:
            self.deliver(self._show, shown(session, rows, verdict))
            self.deliver(self._stage, "latest run shown; r: process again")

    def action_run(self) -> None:
        if self._start is not None:
            self._start.stop()
            self._start = None
        if self.running():
            self.notify("processing is under way: the verdict follows when it is done",
                        severity="warning")
            return
        self._stage("processing ...")
        self._busy = True
        self._process()

    @work(thread=True, exclusive=True, group="process")
    def _process(self) -> None:
        """Process the session, one run at a time in the app (a run given up waits for
        nothing: the next waits for it to stop); leaving the screen or quitting stops it
        at the next stage (nothing is written until a run is complete)."""
        worker = get_current_worker()
        lock = host(self).processing
        if not lock.acquire(blocking=False):
            self.deliver(self._stage, "waiting for the run before to stop ...")
            while not lock.acquire(timeout=0.1):
                if worker.is_cancelled:
                    return
        try:
            self._run_locked(worker)
        finally:
            lock.release()

    def _run_locked(self, worker: object) -> None:
        path = session_of(self).path

        def progress(stage: str, fraction: float) -> None:
            if worker.is_cancelled:  # type: ignore[attr-defined]
                raise Stopped(stage)
            self.deliver(self._progress, stage, fraction)

        try:
            outcome = process_session(path, new_run_id(), progress=progress)
            view = None if outcome.verdict is None else \
                shown(session_of(self), list(outcome.rows), outcome.verdict)
        except Stopped:
            return
        except RigkitError as exc:
            self.deliver(self._failed, str(exc))
            return
        except OSError as exc:  # a full disk, a read-only session
            self.deliver(self._failed, environment_message(exc))
            return
        self.deliver(self._done, view)

    def on_unmount(self) -> None:
        self.workers.cancel_group(self, "process")
        self.workers.cancel_group(self, "resume")

    def _stage(self, markup: str) -> None:
        self.query_one("#stage", Static).update(markup)

    def _progress(self, stage: str, fraction: float) -> None:
        self._stage(f"{escape(stage)} {100 * fraction:.0f} %")
        self.query_one(ProgressBar).update(progress=fraction)

    def _done(self, view: Shown | None) -> None:
        """A run's outcome on show, and the screen free for the next ``r`` or ``e``."""
        if view is not None:
            self._show(view)
        self._stage("done; r: process again")
        self._busy = False

    def _failed(self, message: str) -> None:
        """The error, and no earlier run's table, verdict or depth left beside it."""
        self._busy = False
        self._stage(f"[b $error]✘ {escape(message)}[/]")
        self.query_one(DataTable).clear()
        self.query_one("#verdict", Static).update("")
        self.query_one("#depth", Vertical).remove_children()

    def _show(self, view: Shown) -> None:
        self.query_one(ProgressBar).update(progress=1.0)
        table = self.query_one(DataTable)
        table.clear()
        for row in view.rows:
            table.add_row(*row)
        self.query_one("#verdict", Static).update(view.verdict)
        self.query_one("#verdict-box", VerticalScroll).scroll_home(animate=False)
        box = self.query_one("#depth", Vertical)
        box.remove_children()  # processing again must not mount a second one beside it
        if view.depth is not None:
            box.mount(PixelView(view.depth), Static(_colour_bar(view.lo, view.hi),
                                                    classes="scale"))

    def action_scroll(self, lines: int) -> None:
        self.query_one("#verdict-box", VerticalScroll).scroll_relative(y=lines, animate=False)


def shown(session: Session, rows: Sequence[Comparison], verdict: Verdict) -> Shown:
    """A run of ``session`` (its comparison ``rows`` and the verdict the run returned or,
    reopened, the one :func:`run_verdict` gives its record: the same words) as the
    screen shows it (reads the run's depth: call it off the screen's thread)."""
    table = []
    for row, target in zip(rows, verdict.targets, strict=True):
        error = "" if math.isnan(row.error_pct) else f"{row.error_pct:+.2f} %"
        table.append((row.target, _num(row.laser_range_m), _num(row.estimate_range_m), error,
                      "cal" if target.calibrated else "✔" if target.ok else "✘"))
    markup = verdict_markup(verdict, stray_warnings(session))  # what `rigkit process` says
    try:  # its header first: nothing but a frame-sized map is read
        depth = np.load(RunFiles.of_session(session.path).depth, mmap_mode="r")
    except (OSError, ValueError):
        return Shown(tuple(table), markup, None, 0.0, 0.0)
    if depth.ndim != 2 or depth.size > MAX_FRAME_PIXELS:
        return Shown(tuple(table), markup, None, 0.0, 0.0)
    lo, hi = depth_range(depth)
    image = cv2.cvtColor(colour_map(depth, lo, hi), cv2.COLOR_BGR2RGB)
    return Shown(tuple(table), markup, image, lo, hi)


def verdict_markup(verdict: Verdict, strays: Sequence[str]) -> str:
    """The verdict, most important first: the headline, then what to redo (:func:`redo`),
    then the rest of the advice, what the run found, the scale and where it came from,
    and each target."""
    colour = "$success" if verdict.ok else "$error"
    lines = [f"[b {colour}]{escape(verdict.headline)}[/]"]
    first = redo(verdict)
    if first:
        lines.append(f"[b $warning]redo:[/] {escape(first)}")
    names = tuple(f"{t.target}: " for t in verdict.targets)
    actions = [a for a in verdict.advice if not a.startswith(names) and a != first]
    lines += [f"- {escape(a)}" for a in actions]
    lines += [f"[$warning]{escape(s)}[/]" for s in verdict.shortfalls if s != first]
    if verdict.scale and verdict.scale != first:
        lines.append(f"[b]scale:[/] {escape(verdict.scale)}")
    if verdict.source:
        lines.append(f"[b]rig scale:[/] {escape(verdict.source)}")
    lines += [f"- {escape(a)}" for a in verdict.advice if a.startswith(names)]
    lines += [f"[$warning]{escape(s)}[/]" for s in strays]
    return "\n".join(lines)


def redo(verdict: Verdict) -> str:
    """What to do next after a verdict that is not "done", one line ("" when done): the
    scale where the lasers say the taped C_lb is off (every target follows it), then
    what the run says it misses the goal by (a burst too short, the offset), then the
    verdict's first action."""
    if verdict.ok:
        return ""
    if "re-tape" in verdict.scale:
        return verdict.scale
    if verdict.shortfalls:
        return verdict.shortfalls[0]
    names = tuple(f"{t.target}: " for t in verdict.targets)
    actions = [a for a in verdict.advice if not a.startswith(names)]
    return actions[0] if actions else ""


def _colour_bar(lo: float, hi: float, steps: int = 6) -> Text:
    """The depth preview's scale in text, two short lines that fit under a preview 14
    columns wide (a 60-column terminal): ``depth z, m`` over ``289 ██████ 312``."""
    bar = Text(f"depth z, m\n{lo:.0f} ")
    for rgb in scale_colours(steps):
        bar.append("█", style=f"rgb({rgb[0]},{rgb[1]},{rgb[2]})")
    bar.append(f" {hi:.0f}")
    return bar


def _num(value: float) -> str:
    return "-" if math.isnan(value) else f"{value:.1f}"
