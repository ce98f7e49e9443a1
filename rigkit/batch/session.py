"""Processing one capture session: depth, previews and laser comparisons.

:func:`process_session` takes the session's lock, runs the depth run on its frames
(:func:`rigkit.batch.depthrun.run_depth`, as ``rigkit depth`` does), compares every
laser target with the depth map (:mod:`rigkit.batch.compare`),
writes ``results/`` as a whole (:func:`rigkit.core.files.replace_folder`: staged in a
hidden folder, then swapped in) and appends one row per target to the session's
``comparisons.csv``. :mod:`rigkit.batch.pool` runs many sessions.
"""

from __future__ import annotations

import secrets
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from datetime import UTC, datetime
from pathlib import Path

import numpy as np

from rigkit.batch.compare import compare_target
from rigkit.batch.depthrun import run_depth
from rigkit.capture.actions import changing, frame_problems, session_frames
from rigkit.capture.comparisons import LOG_NAME, Comparison, append_rows, csv_text
from rigkit.capture.model import DERIVED_DIR, HISTORY_FILE, Session, stray_readings
from rigkit.capture.results import RESULTS_DIR, RunFiles, session_record
from rigkit.capture.session import load_session, log_event, utc_now
from rigkit.core.files import Content, check_free_space, replace_folder
from rigkit.core.safefs import check_regular
from rigkit.errors import InputError
from rigkit.reporting.previews import preview_set
from rigkit.reporting.verdict import Verdict, run_verdict

StageReport = Callable[[str, float], None]
RESULT_BYTES_PER_PIXEL = 13
"""What a run writes into ``results/``, per pixel of a frame: depth and sigma (float32
each), the previews, grey and flags (10.9 bytes per pixel measured on the bundled
example before the flags, which add at most one)."""


def new_run_id() -> str:
    """A run id that sorts by time: ``20261122T101530Z-3fa2``."""
    return datetime.now(UTC).strftime("%Y%m%dT%H%M%SZ") + "-" + secrets.token_hex(2)


@dataclass(frozen=True)
class Outcome:
    """What happened to one session: ``ok`` with its comparisons, or the reason it failed.

    ``warnings`` are one-line findings that did not stop processing (EXIF differences,
    the offset's share of depth); ``verdict`` what the laser targets say of the run
    (:func:`rigkit.reporting.verdict.judge`; None for a failed session).
    """

    path: Path
    ok: bool
    message: str
    seconds: float
    rows: tuple[Comparison, ...] = ()
    warnings: tuple[str, ...] = field(default=())
    verdict: Verdict | None = None


# -- one session ----------------------------------------------------------------------------


BRIEF_HOLD_S = 2.0
"""How long processing waits for the session's lock: a change such as a target added or
the field TUI recording its step holds it for a moment; another processing run holds it
for as long as it takes, and is named instead of waited for."""


def process_session(
    path: str | Path,
    run_id: str,
    *,
    force: bool = False,
    progress: StageReport | None = None,
) -> Outcome:
    """Process one session folder; RigkitError (one line) if it cannot be processed.

    Nothing under ``raw/`` is touched; ``results/`` is replaced only once the new
    results are completely written. The session is locked meanwhile
    (:func:`rigkit.capture.actions.changing`, which first repairs what an interrupted
    command left): a change to it waits, or is refused with who holds it; processing
    itself waits :data:`BRIEF_HOLD_S` for a change under way.
    """
    t0 = time.perf_counter()
    report = progress or (lambda stage, fraction: None)
    path = Path(path)
    load_session(path)  # a clear error for a folder that is no session, before locking
    with changing(path, "process", wait_s=BRIEF_HOLD_S) as session:
        return _process_locked(session, run_id, force, report, t0)


def _process_locked(
    session: Session, run_id: str, force: bool, report: StageReport, t0: float
) -> Outcome:
    if _run_of_results(session.path) == run_id:  # a task run again (a Dask worker lost)
        log_event(session.path, "process", f"run {run_id}: already done; left as it is")
        return Outcome(session.path, True, f"already processed in run {run_id}",
                       time.perf_counter() - t0)
    problems = frame_problems(session)
    if problems:
        raise InputError(f"{session.path}: " + "; ".join(problems))
    for log in (HISTORY_FILE, LOG_NAME):  # the run appends to them once its results are in
        check_regular(session.path / log)
    width, height = session.rig().image_size
    check_free_space(session.path, RESULT_BYTES_PER_PIXEL * width * height, str(session.path))
    try:
        run = run_depth(session_frames(session), session.rig(),
                        cache_dir=session.path / DERIVED_DIR, force=force,
                        progress=lambda stage, f: report(stage, 0.9 * f))
    except InputError as exc:
        raise InputError(f"{session.path}: {exc}") from None
    result = run.result
    record = run.record(session.targets, run_id, utc_now())
    lens = record.left_lens  # the lens rigkit export back-projects through
    rows = tuple(
        compare_target(session, target, result.depth, result.sigma, run_id, lens,
                       (result.offset_depth_fraction, result.median_depth_m))
        for target in session.targets
    )
    report("writing results", 0.92)
    files: dict[str, Content] = {
        **run.outputs(RunFiles.of_session(session.path), record),
        **preview_set(run.left, result.depth, result.sigma, session.targets, rows,
                      result.disagree),
    }
    if rows:
        files[LOG_NAME] = csv_text(rows)
    replace_folder(session.path, RESULTS_DIR, files, run_id)
    if rows:
        append_rows(session.path / LOG_NAME, rows)
    seconds = time.perf_counter() - t0
    log_event(session.path, "process", f"run {run_id}: ok, {len(rows)} targets, {seconds:.1f} s")
    report("done", 1.0)
    density = float(np.isfinite(result.depth).mean())
    verdict = run_verdict(session, rows, run.profile, record)
    return Outcome(
        session.path, True, f"density {100 * density:.1f} %, {len(rows)} targets",
        seconds, rows, (*run.warnings, *stray_warnings(session)), verdict,
    )


def _run_of_results(path: Path) -> str | None:
    """The run id of the session's results (None: none, or unreadable). Results and
    their rows are written under the lock, whole, once per run: a run id found here
    means this run's work is done (exactly once, whatever a cluster retries)."""
    try:
        record = session_record(path)
    except InputError:  # refused: no run's work is done
        return None
    return record.run_id if record is not None else None


def stray_warnings(session: Session) -> list[str]:
    """One line per reading far from its target's others (:func:`stray_readings`)."""
    lines = []
    for target in session.targets:
        for index in stray_readings(target):
            value = target.readings[index].slope_distance_m
            lines.append(f"{target.name}: reading {index + 1} ({value:.2f} m) is far from the "
                         f"others; the median is used (a typo? `rigkit session remove-reading "
                         f"{session.path} --target {target.name} --reading {index + 1}`)")
    return lines
