"""Processing one capture session: depth, previews and laser comparisons.

:func:`process_session` takes the session's lock, runs the depth pipeline on its
frames, compares every laser target with the depth map (:mod:`rigkit.batch.compare`),
writes ``results/`` as a whole (:func:`rigkit.core.files.replace_folder`: staged in a
hidden folder, then swapped in) and appends one row per target to the session's
``comparisons.csv``. :mod:`rigkit.batch.pool` runs many sessions.
"""

from __future__ import annotations

import fcntl
import json
import secrets
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

import numpy as np

from rigkit import __version__
from rigkit.batch.compare import compare_target
from rigkit.capture.actions import frame_problems
from rigkit.capture.checks import session_warnings
from rigkit.capture.comparisons import LOG_NAME, Comparison, append_rows, csv_text
from rigkit.capture.frames import load_frames
from rigkit.capture.session import (
    POSITIONS,
    RESULTS_DIR,
    Frame,
    Session,
    load_session,
    log_event,
    utc_now,
)
from rigkit.core.files import Content, replace_folder
from rigkit.errors import InputError
from rigkit.pipeline import estimate_depth
from rigkit.reporting.previews import preview_set
from rigkit.rig.budget import burst_warning

LOCK_FILE = ".lock"

StageReport = Callable[[str, float], None]


def new_run_id() -> str:
    """A run id that sorts by time: ``20261122T101530Z-3fa2``."""
    return datetime.now(UTC).strftime("%Y%m%dT%H%M%SZ") + "-" + secrets.token_hex(2)


@dataclass(frozen=True)
class Outcome:
    """What happened to one session: ``ok`` with its comparisons, or the reason it failed.

    ``warnings`` are one-line findings that did not stop processing (EXIF differences).
    """

    path: Path
    ok: bool
    message: str
    seconds: float
    rows: tuple[Comparison, ...] = ()
    warnings: tuple[str, ...] = field(default=())


def _frames_meta(burst: tuple[Frame, ...]) -> Any:
    """A position's file and hash; a list of them for a burst (as in session.yaml)."""
    files = [{"file": f.file, "sha256": f.sha256} for f in burst]
    return files[0] if len(files) == 1 else files


# -- one session ----------------------------------------------------------------------------


def process_session(
    path: str | Path,
    run_id: str,
    *,
    force: bool = False,
    progress: StageReport | None = None,
) -> Outcome:
    """Process one session folder; RigkitError (one line) if it cannot be processed.

    Nothing under ``raw/`` is touched; ``results/`` is replaced only once the new
    results are completely written.
    """
    t0 = time.perf_counter()
    report = progress or (lambda stage, fraction: None)
    session = load_session(path)
    with _exclusive(session.path):
        return _process_locked(session, run_id, force, report, t0)


@contextmanager
def _exclusive(session_path: Path) -> Iterator[None]:
    """Hold the session's lock, so two runs never write one session at once. The OS
    drops the lock when its process ends, so a crash leaves nothing to clean up."""
    try:
        handle = open(session_path / LOCK_FILE, "a")  # closed by the with below
    except OSError as exc:
        raise InputError(f"{session_path}: cannot write to the session ({exc.strerror})") from None
    with handle:
        try:
            fcntl.flock(handle, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            raise InputError(
                f"{session_path}: being processed by another rigkit run; try again later"
            ) from None
        yield


def _process_locked(
    session: Session, run_id: str, force: bool, report: StageReport, t0: float
) -> Outcome:
    problems = frame_problems(session)
    if problems:
        raise InputError(f"{session.path}: " + "; ".join(problems))
    profile = session.rig()
    warnings = session_warnings(session, force)
    report("reading frames", 0.02)
    (left, right, back), shimmer = load_frames(session)
    report("reading frames", 0.1)
    rig = profile.geometry()
    result = estimate_depth(
        left, right, back, rig, progress=lambda stage, f: report(stage, 0.1 + 0.8 * f),
        settings=profile.pipeline_settings(),
    )
    rows = tuple(
        compare_target(session, target, result.depth, result.sigma, run_id)
        for target in session.targets
    )
    offset_warning = result.offset_warning()
    if offset_warning:
        warnings = (*warnings, offset_warning)
    if shimmer is not None:
        measured, where = shimmer
        short = burst_warning(measured, where, (left.shape[1], left.shape[0]), rig.focal_px,
                              rig.baseline_lr_m, result.median_depth_m, session.burst_length)
        warnings = (*warnings, short) if short else warnings
    report("writing results", 0.92)
    meta = {
        "run_id": run_id,
        "rigkit_version": __version__,
        "time_utc": utc_now(),
        "frames": {pos: _frames_meta(session.bursts[pos]) for pos in POSITIONS},
        "rig": {"name": profile.name, "focal_px": rig.focal_px,
                "baseline_lr_m": rig.baseline_lr_m, "baseline_lb_m": rig.baseline_lb_m,
                "distortion_k1_k2_p1_p2_k3": list(rig.distortion)},
        "warnings": list(warnings),
        "shimmer": {"frames": shimmer[1], **shimmer[0].as_dict()} if shimmer else None,
        **result.diagnostics(),
    }
    files: dict[str, Content] = {
        "depth.npy": result.depth,
        "sigma.npy": result.sigma,
        "depth.json": json.dumps(meta, indent=2),
        **preview_set(left, result.depth, result.sigma, session.targets, rows),
    }
    if rows:
        files["comparisons.csv"] = csv_text(rows)
    replace_folder(session.path, RESULTS_DIR, files, run_id)
    if rows:
        append_rows(session.path / LOG_NAME, rows)
    seconds = time.perf_counter() - t0
    log_event(session.path, "process", f"run {run_id}: ok, {len(rows)} targets, {seconds:.1f} s")
    report("done", 1.0)
    density = float(np.isfinite(result.depth).mean())
    return Outcome(
        session.path, True, f"density {100 * density:.1f} %, {len(rows)} targets",
        seconds, rows, warnings,
    )
