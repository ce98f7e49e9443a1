"""The process step: run the depth, show it with the laser comparisons and the verdict."""

from __future__ import annotations

import math
from pathlib import Path

import cv2
import numpy as np
from rich.text import Text
from textual import work
from textual.app import ComposeResult
from textual.binding import Binding
from textual.containers import Horizontal, Vertical, VerticalScroll
from textual.widgets import DataTable, Footer, Header, ProgressBar, Static
from textual.worker import get_current_worker

from rigkit.batch import new_run_id, process_session
from rigkit.batch.session import stray_warnings
from rigkit.capture import frame_problems, read_rows
from rigkit.capture.comparisons import LOG_NAME, Comparison, latest_run
from rigkit.capture.results import RunFiles, session_record, stale_results
from rigkit.errors import RigkitError, environment_message
from rigkit.imagefile.imagesize import MAX_FRAME_PIXELS
from rigkit.reporting.previews import colour_map, depth_range, scale_colours
from rigkit.reporting.verdict import Verdict, run_verdict
from rigkit.tui.screens.common import escape, session_of
from rigkit.tui.screens.exporting import ExportingScreen
from rigkit.tui.widgets import PixelView


class Stopped(Exception):
    """Processing given up because its screen closed (raised from the progress report)."""


class ProcessScreen(ExportingScreen):
    """Run the depth pipeline; show the depth, the laser comparisons and the verdict;
    ``e`` exports the results (:mod:`rigkit.tui.screens.exporting`)."""

    step = "process"
    BINDINGS = [Binding("r", "run", "process")]

    def __init__(self, resume: bool = False) -> None:
        """``resume``: show the latest run if there is one, instead of processing."""
        super().__init__()
        self.resume = resume

    def compose(self) -> ComposeResult:
        yield Header()
        with VerticalScroll(id="stage-box"):  # more than fits scrolls, never cut off
            yield Static("", id="stage")
        yield ProgressBar(total=1.0, show_eta=False, id="progress")
        with Horizontal():
            yield Vertical(id="depth")
            yield DataTable(id="rows", cursor_type="none")
        with VerticalScroll(id="verdict-box"):
            yield Static("", id="verdict")
        yield Footer(compact=True)

    def on_mount(self) -> None:
        table = self.query_one(DataTable)
        table.add_columns("target", "laser m", "depth m", "error", "≤1 %")
        if not self.resume:
            self.action_run()
        else:  # reopened here: processing waits to be asked for
            self.query_one("#stage", Static).update("reading the latest run ...")
            self._resume()

    @work(thread=True, exclusive=True, group="process")
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
        if get_current_worker().is_cancelled:  # r was pressed meanwhile: its run shows
            return
        if not done:
            self.app.call_from_thread(self.query_one("#stage", Static).update,
                                      "not processed yet; r: process")
            return
        if why or verdict is None:
            self.app.call_from_thread(self._failed, f"{why or 'no results'}; r: process again")
            return
        self.app.call_from_thread(self._show_results, rows, verdict)
        self.app.call_from_thread(self.query_one("#stage", Static).update,
                                  "latest run shown; r: process again")

    def action_run(self) -> None:
        self.query_one("#stage", Static).update("processing ...")
        self._process()

    @work(thread=True, exclusive=True, group="process")
    def _process(self) -> None:
        """Process the session; leaving the screen or quitting stops it at the next stage
        (nothing is written until a run is complete)."""
        path = session_of(self).path
        worker = get_current_worker()

        def progress(stage: str, fraction: float) -> None:
            if worker.is_cancelled:
                raise Stopped(stage)
            self.app.call_from_thread(self._progress, stage, fraction)

        try:
            outcome = process_session(path, new_run_id(), progress=progress)
        except Stopped:
            return
        except RigkitError as exc:
            self.app.call_from_thread(self._failed, str(exc))
            return
        except OSError as exc:  # a full disk, a read-only session
            self.app.call_from_thread(self._failed, environment_message(exc))
            return
        if outcome.verdict is not None:
            self.app.call_from_thread(self._show_results, list(outcome.rows), outcome.verdict)

    def on_unmount(self) -> None:
        self.workers.cancel_group(self, "process")

    def _progress(self, stage: str, fraction: float) -> None:
        self.query_one("#stage", Static).update(f"{stage} {100 * fraction:.0f} %")
        self.query_one(ProgressBar).update(progress=fraction)

    def _failed(self, message: str) -> None:
        """The error, and no earlier run's table, verdict or depth left beside it."""
        self.query_one("#stage", Static).update(f"[b $error]✘ {escape(message)}[/]")
        self.query_one(DataTable).clear()
        self.query_one("#verdict", Static).update("")
        self.query_one("#depth", Vertical).remove_children()

    def _show_results(self, rows: list[Comparison], verdict: Verdict) -> None:
        """The run's rows and the verdict it returned (or, reopened, the one
        :func:`run_verdict` gives its record: the same words)."""
        session = session_of(self)
        self.query_one(ProgressBar).update(progress=1.0)
        table = self.query_one(DataTable)
        table.clear()
        for row, target in zip(rows, verdict.targets, strict=True):
            error = "" if math.isnan(row.error_pct) else f"{row.error_pct:+.2f} %"
            table.add_row(row.target, _num(row.laser_range_m), _num(row.estimate_range_m),
                          error, "cal" if target.calibrated else "✔" if target.ok else "✘")
        colour = "$success" if verdict.ok else "$error"
        advice = "".join(f"\n- {escape(a)}" for a in verdict.advice)
        notes = [*verdict.shortfalls, *stray_warnings(session)]  # as `rigkit process` prints
        advice += "".join(f"\n[$warning]{escape(note)}[/]" for note in notes)
        if verdict.scale:
            advice += f"\n[b]scale:[/] {escape(verdict.scale)}"
        advice += f"\n[b]rig scale:[/] {escape(verdict.source)}"
        self.query_one("#verdict", Static).update(
            f"[b {colour}]{escape(verdict.headline)}[/]{advice}")
        self.call_later(self._show_depth, RunFiles.of_session(session.path).depth)

    async def _show_depth(self, path: Path) -> None:
        """The depth map's preview and its scale, in place of the previous run's (removed
        first: processing again must not mount a second one beside it)."""
        box = self.query_one("#depth", Vertical)
        await box.remove_children()
        try:  # its header first: nothing but a frame-sized map is read
            depth = np.load(path, mmap_mode="r")
        except (OSError, ValueError):
            return
        if depth.ndim != 2 or depth.size > MAX_FRAME_PIXELS:
            return
        lo, hi = depth_range(depth)
        image = cv2.cvtColor(colour_map(depth, lo, hi), cv2.COLOR_BGR2RGB)
        await box.mount(PixelView(image), Static(_colour_bar(lo, hi), classes="scale"))


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
