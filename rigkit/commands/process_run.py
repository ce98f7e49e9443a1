"""Running ``rigkit process`` (its arguments: :mod:`rigkit.commands.process`)."""

from __future__ import annotations

import argparse
import os
import sys
from collections.abc import Callable
from pathlib import Path

from rigkit.batch import auto_jobs, new_run_id, run_batch
from rigkit.batch.pool import BatchReport
from rigkit.batch.session import Outcome
from rigkit.core.progress import Progress
from rigkit.core.tables import visible
from rigkit.errors import InputError


def run(args: argparse.Namespace) -> int:
    # One session named twice (a link to it, ./s and s/) is processed once: twice in
    # one run, the second would find it locked by the first and say it failed.
    named: dict[str, Path] = {}
    for path in args.sessions:
        named.setdefault(os.path.realpath(path), path)
    paths = list(named.values())
    if args.jobs is not None and args.jobs < 1:
        raise InputError(f"--jobs {args.jobs}: expected at least 1")
    where, process = _runner(args, paths)
    run_id = new_run_id()
    names = _task_names(paths)
    print(f"run {run_id}: {len(paths)} session(s), {where}", file=sys.stderr)
    with Progress("process", list(names.values()), quiet=args.quiet) as progress:

        def update(path: Path, stage: str, fraction: float) -> None:
            progress.update(names[path], fraction, stage)

        def finished(outcome: Outcome) -> None:
            progress.done(names[outcome.path])
            for line in _outcome_lines(outcome):
                progress.print(visible(line, lines=False))

        outcomes = process(run_id, update, finished)
    failed = [o for o in outcomes if not o.ok]
    print(f"run {run_id}: {len(outcomes) - len(failed)} processed, {len(failed)} failed "
          f"({progress.elapsed():.1f} s)")
    for outcome in failed:
        print(f"  FAILED {visible(_reason(outcome), lines=False)}")
    return 1 if failed else 0


Runs = Callable[[str, BatchReport, Callable[[Outcome], None]], list[Outcome]]
"""A way to run the sessions: ``(run_id, update, finished) -> outcomes``."""


def _runner(args: argparse.Namespace, paths: list[Path]) -> tuple[str, Runs]:
    """Where the sessions will run, in words, and the call ``(run_id, update, finished)
    -> outcomes`` that runs them: local worker processes, or a Dask cluster's workers
    (reached, with a worker, before anything starts)."""
    if args.scheduler is None:
        jobs = args.jobs or auto_jobs(paths)
        return f"{jobs} at a time", lambda run_id, update, finished: list(run_batch(
            paths, jobs, run_id=run_id, force=args.force, progress=update, on_done=finished))
    if args.jobs is not None:
        raise InputError("--jobs applies to local processes; with --scheduler the cluster's "
                         "workers decide how many sessions run at once")
    from rigkit.batch.cluster import connect, run_on_cluster  # imports Dask: only here

    client = connect(args.scheduler)

    def on_cluster(run_id: str, update: BatchReport, finished: Callable[[Outcome], None]
                   ) -> list[Outcome]:
        with client:
            return list(run_on_cluster(paths, client, run_id=run_id, force=args.force,
                                       on_done=finished))

    workers = len(client.scheduler_info()["workers"])
    return f"on the {workers} worker(s) of {args.scheduler}", on_cluster


def _task_names(paths: list[Path]) -> dict[Path, str]:
    """How the progress display names each session: its folder name, or its path where
    two folders share a name."""
    names = [path.name for path in paths]
    return {path: path.name if names.count(path.name) == 1 else str(path) for path in paths}


def _reason(outcome: Outcome) -> str:
    """The failure message, naming the session once."""
    prefix = f"{outcome.path}: "
    return outcome.message if outcome.message.startswith(prefix) else prefix + outcome.message


def _outcome_lines(outcome: Outcome) -> list[str]:
    """What a finished session reports: ok or FAILED, warnings, one line per target."""
    if outcome.ok:
        lines = [f"    ok {outcome.path} ({outcome.seconds:.1f} s): {outcome.message}"]
    else:
        lines = [f"FAILED {_reason(outcome)}"]
    lines += [f"       warning: {warning}" for warning in outcome.warnings]
    if outcome.verdict is None:
        return lines
    lines += [
        f"       {row.target:<8} laser {row.laser_range_m:8.2f} m  estimate "
        f"{row.estimate_range_m:8.2f} m  {row.error_pct:+6.2f} %  "
        f"(+- {row.estimate_sigma_m:.2f} m)  {target.label}"
        for row, target in zip(outcome.rows, outcome.verdict.targets, strict=True)
    ]
    lines.append(f"       verdict: {outcome.verdict.headline}")
    if outcome.verdict.scale:
        lines.append(f"       scale: {outcome.verdict.scale}")
    if outcome.verdict.source:
        lines.append(f"       rig scale {outcome.verdict.source}")
    return lines
