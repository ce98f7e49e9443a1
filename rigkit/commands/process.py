"""``rigkit process``: depth, previews and laser comparisons for capture sessions."""

from __future__ import annotations

import argparse
import shutil
import sys
import time
from pathlib import Path
from typing import Any

EXAMPLE = """examples:
  rigkit process capture/example
  rigkit process capture/* --jobs 2

for each session writes SESSION/results/ (depth.npy, sigma.npy, depth.json, depth.png
and left.png with the targets marked, sigma.png, comparisons.csv), replacing the previous
results as a whole, and appends one row per target to SESSION/comparisons.csv.
A session that fails is reported and the others go on; the exit code is 1 if any failed.
"""


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "process",
        help="process capture sessions: depth, previews, rangefinder comparisons",
        description="Run the depth pipeline on each session and compare the estimate "
        "with every laser-ranged target (docs/sessions.md).",
        epilog=EXAMPLE,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("sessions", type=Path, nargs="+", metavar="SESSION", help="session folders")
    p.add_argument("--jobs", type=int, help="sessions processed at once (default: as many "
                   "as cores and free memory allow)")
    p.add_argument("--force", action="store_true",
                   help="process despite an EXIF focal length that contradicts the rig")
    p.add_argument("--quiet", action="store_true", help="no progress output")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from rigkit.batch import auto_jobs, new_run_id, run_batch
    from rigkit.errors import InputError

    paths = list(dict.fromkeys(args.sessions))
    if args.jobs is not None and args.jobs < 1:
        raise InputError(f"--jobs {args.jobs}: expected at least 1")
    jobs = args.jobs or auto_jobs(paths)
    run_id = new_run_id()
    board = Board(paths, quiet=args.quiet)
    print(f"run {run_id}: {len(paths)} session(s), {jobs} at a time", file=sys.stderr)
    outcomes = run_batch(paths, jobs, run_id=run_id, force=args.force,
                         progress=board.update, on_done=board.finished)
    failed = [o for o in outcomes if not o.ok]
    print(f"run {run_id}: {len(outcomes) - len(failed)} processed, {len(failed)} failed "
          f"({board.elapsed():.1f} s)")
    for outcome in failed:
        print(f"  FAILED {_reason(outcome)}")
    return 1 if failed else 0


def _reason(outcome: Any) -> str:
    """The failure message, naming the session once."""
    prefix = f"{outcome.path}: "
    return outcome.message if outcome.message.startswith(prefix) else prefix + outcome.message


def _bar(fraction: float, width: int = 10) -> str:
    filled = round(fraction * width)
    return "[" + "#" * filled + "." * (width - filled) + "]"


class Board:
    """Per-session stage progress and an ETA for the whole batch, on stderr.

    On a terminal one line is rewritten in place, with a bar per running session;
    otherwise (a log file) one line per stage.
    """

    def __init__(self, paths: list[Path], quiet: bool) -> None:
        self.fraction = {path: 0.0 for path in paths}
        self.stage = {path: "waiting" for path in paths}
        self.quiet = quiet
        self.tty = sys.stderr.isatty()
        self.t0 = time.perf_counter()

    def elapsed(self) -> float:
        return time.perf_counter() - self.t0

    def eta(self) -> str:
        done = sum(self.fraction.values()) / max(len(self.fraction), 1)
        if done <= 0.02:
            return "ETA --"
        remaining = self.elapsed() * (1 - done) / done
        return f"ETA {remaining:.0f} s" if remaining < 120 else f"ETA {remaining / 60:.1f} min"

    def update(self, path: Path, stage: str, fraction: float) -> None:
        self.fraction[path] = max(self.fraction.get(path, 0.0), fraction)
        self.stage[path] = stage
        if self.quiet:
            return
        total = 100 * sum(self.fraction.values()) / max(len(self.fraction), 1)
        head = f"[{total:3.0f}% {self.eta()}]"
        if not self.tty:
            print(f"{head} {path.name}: {stage} {100 * fraction:3.0f}%", file=sys.stderr,
                  flush=True)
            return
        running = [p for p, f in self.fraction.items() if 0 < f < 1]
        bars = " | ".join(f"{p.name} {self.stage[p]} {_bar(self.fraction[p])}" for p in running)
        width = shutil.get_terminal_size().columns - 1
        print(f"\r{head} {bars}"[: width + 1] + "\033[K", end="", file=sys.stderr, flush=True)

    def finished(self, outcome: Any) -> None:
        self.fraction[outcome.path] = 1.0
        clear = "\r\033[K" if self.tty and not self.quiet else ""
        if outcome.ok:
            line = f"    ok {outcome.path} ({outcome.seconds:.1f} s): {outcome.message}"
        else:
            line = f"FAILED {_reason(outcome)}"
        print(clear + line, file=sys.stderr, flush=True)
        for warning in outcome.warnings:
            print(f"       warning: {warning}", file=sys.stderr)
        for row in outcome.rows:
            print(f"       {row.target:<8} laser {row.laser_range_m:8.2f} m  estimate "
                  f"{row.estimate_range_m:8.2f} m  {row.error_pct:+6.2f} %  "
                  f"(+- {row.estimate_sigma_m:.2f} m) {row.status}", file=sys.stderr)
