"""The one progress display for long work (``rigkit depth``, ``synth``, ``process``).

Progress is reported per task as a fraction done, optionally with the stage the task is
in: ``progress.update("left", 0.5)`` or ``progress.update("seed-7", 0.4, "stereo")``.

* On a terminal it is a live rich display: one bar per task with its stage, percentage
  and ETA, plus an overall bar when there are several tasks; :meth:`Progress.print`
  writes lines above the bars.
* Elsewhere (a log file, CI) it writes plain lines, one when a task enters a new stage
  or passes a quarter, so logs stay short: ``[ 26% ETA 9 s] seed-7: matching 26%``.
* ``quiet`` silences the progress (lines given to :meth:`Progress.print` still appear).

Use it as a context manager (or call :meth:`close`) so the live display ends cleanly.
"""

from __future__ import annotations

import sys
import time
from collections.abc import Sequence
from types import TracebackType
from typing import IO

from rich.console import Console
from rich.progress import (
    BarColumn,
    TaskID,
    TaskProgressColumn,
    TextColumn,
    TimeElapsedColumn,
    TimeRemainingColumn,
)
from rich.progress import Progress as RichProgress

from rigkit.core.tables import visible

OVERALL = "all"


class Progress:
    """Per-task progress on ``file`` (default stderr); see the module."""

    def __init__(
        self,
        label: str,
        tasks: Sequence[str] = (),
        *,
        quiet: bool = False,
        file: IO[str] | None = None,
    ) -> None:
        self.label = label
        self.quiet = quiet
        self.file = file if file is not None else sys.stderr
        self.tty = self.file.isatty()
        self.t0 = time.perf_counter()
        self.fraction: dict[str, float] = dict.fromkeys(tasks, 0.0)
        self.stage: dict[str, str] = {}
        self._printed: dict[str, tuple[str, int]] = {}
        self._console = Console(file=self.file, highlight=False, soft_wrap=True)
        self._live: RichProgress | None = None
        self._ids: dict[str, TaskID] = {}

    # -- reporting -------------------------------------------------------------------

    def __call__(self, task: str, fraction: float) -> None:
        """``update(task, fraction)``: the callback shape the pipeline and renderer use."""
        self.update(task, fraction)

    def update(self, task: str, fraction: float, stage: str = "") -> None:
        """Task ``task`` is ``fraction`` (0-1) done, now in ``stage`` (may be empty)."""
        fraction = min(max(fraction, 0.0), 1.0)
        self.fraction[task] = max(self.fraction.get(task, 0.0), fraction)
        if stage:
            self.stage[task] = stage
        if self.quiet:
            return
        if self.tty:
            self._show_live(task)
        else:
            self._show_line(task)

    def done(self, task: str) -> None:
        """Mark ``task`` complete (e.g. a session that failed half-way)."""
        self.update(task, 1.0)

    def print(self, line: str) -> None:
        """A line of output (shown even when quiet), above the bars on a terminal."""
        if self._live is not None:
            self._live.console.print(visible(line), markup=False, highlight=False)
        else:
            print(visible(line), file=self.file, flush=True)

    def elapsed(self) -> float:
        return time.perf_counter() - self.t0

    def overall(self) -> float:
        """Mean fraction done over all tasks (0 with none)."""
        return sum(self.fraction.values()) / max(len(self.fraction), 1)

    def eta(self) -> str:
        done = self.overall()
        if done <= 0.02:
            return "ETA --"
        remaining = self.elapsed() * (1 - done) / done
        return f"ETA {remaining:.0f} s" if remaining < 120 else f"ETA {remaining / 60:.1f} min"

    # -- plain lines -----------------------------------------------------------------

    def _show_line(self, task: str) -> None:
        pct = round(100 * self.fraction[task])
        stage = self.stage.get(task, "")
        mark = (stage, pct // 25)
        if self._printed.get(task) == mark:
            return
        self._printed[task] = mark
        what = visible(f"{task}: {stage}" if stage else task, lines=False)
        head = f"[{100 * self.overall():3.0f}% {self.eta()}] {self.label}"
        print(f"{head}: {what} {pct}% ({self.elapsed():.1f} s)", file=self.file, flush=True)

    # -- live display ----------------------------------------------------------------

    def _show_live(self, task: str) -> None:
        if self._live is None:
            self._live = RichProgress(
                TextColumn("{task.description}", markup=False),  # names shown as they are
                BarColumn(),
                TaskProgressColumn(),
                TimeRemainingColumn(),
                TimeElapsedColumn(),
                console=self._console,
            )
            self._live.start()
            if len(self.fraction) > 1:
                self._ids[OVERALL] = self._live.add_task(f"{self.label}: all", total=100)
        if task not in self._ids:
            self._ids[task] = self._live.add_task(visible(task, lines=False), total=100)
        stage = self.stage.get(task, "")
        self._live.update(
            self._ids[task],
            completed=100 * self.fraction[task],
            description=visible(f"{self.label}: {task}" + (f" ({stage})" if stage else ""),
                                lines=False),
        )
        self._update_overall()

    def _update_overall(self) -> None:
        if self._live is not None and OVERALL in self._ids:
            self._live.update(self._ids[OVERALL], completed=100 * self.overall())

    # -- lifetime --------------------------------------------------------------------

    def close(self) -> None:
        """End the live display (a no-op for plain lines)."""
        if self._live is not None:
            self._live.stop()
            self._live = None

    def __enter__(self) -> Progress:
        return self

    def __exit__(
        self,
        kind: type[BaseException] | None,
        error: BaseException | None,
        trace: TracebackType | None,
    ) -> None:
        self.close()
