"""Headless processing of capture sessions: depth, previews and laser comparisons.

:func:`process_session` runs the depth pipeline on one session folder, writes its
``results/`` as a whole (staged in a hidden folder, then swapped in) and appends one
row per target to its ``comparisons.csv``. :func:`run_batch` does that for many
sessions, in parallel processes with memory-bounded concurrency, and never lets one
failing session stop the others.
"""

from __future__ import annotations

import fcntl
import json
import math
import multiprocessing
import os
import secrets
import threading
import time
import traceback
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures import Future, ProcessPoolExecutor, as_completed
from contextlib import contextmanager
from dataclasses import dataclass, field
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

import numpy as np

from rigkit import __version__
from rigkit.capture import (
    POSITIONS,
    RESULTS_DIR,
    Session,
    Target,
    frame_problems,
    is_session,
    load_session,
    log_event,
    utc_now,
)
from rigkit.capture.checks import session_warnings
from rigkit.capture.comparisons import (
    LOG_NAME,
    STATUS_NO_ESTIMATE,
    STATUS_NO_READING,
    STATUS_OK,
    Comparison,
    append_rows,
    csv_text,
)
from rigkit.core.files import Content, replace_folder
from rigkit.errors import InputError, RigkitError
from rigkit.rangefinder.ranging import profile_range_from_depth

#: Memory a session needs, per pixel of one frame, at the peak of decoding and the
#: pipeline (measured by benchmarks/bench_process.py), plus a fixed overhead.
BYTES_PER_PIXEL = 130
BASE_BYTES = 400 * 2**20
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
    from rigkit.capture.frames import load_frames
    from rigkit.pipeline import RigGeometry, estimate_depth

    problems = frame_problems(session)
    if problems:
        raise InputError(f"{session.path}: " + "; ".join(problems))
    profile = session.rig()
    warnings = session_warnings(session, force)
    report("reading frames", 0.02)
    left, right, back = load_frames(session)
    report("reading frames", 0.1)
    rig = RigGeometry(profile.focal_px, profile.baseline_lr.value_m, profile.baseline_lb.value_m)
    result = estimate_depth(
        left, right, back, rig, progress=lambda stage, f: report(stage, 0.1 + 0.8 * f)
    )
    rows = tuple(
        compare_target(session, target, result.depth, result.sigma, run_id)
        for target in session.targets
    )
    report("writing results", 0.92)
    meta = {
        "run_id": run_id,
        "rigkit_version": __version__,
        "time_utc": utc_now(),
        "frames": {
            pos: {"file": session.frames[pos].file, "sha256": session.frames[pos].sha256}
            for pos in POSITIONS
        },
        "rig": {"name": profile.name, "focal_px": rig.focal_px,
                "baseline_lr_m": rig.baseline_lr_m, "baseline_lb_m": rig.baseline_lb_m},
        "warnings": list(warnings),
        **result.diagnostics(),
    }
    files: dict[str, Content] = {
        "depth.npy": result.depth,
        "sigma.npy": result.sigma,
        "depth.json": json.dumps(meta, indent=2),
        **_previews(left, result.depth, result.sigma, session.targets, rows),
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


# -- comparing targets with the depth map ----------------------------------------------------


def compare_target(
    session: Session, target: Target, depth: np.ndarray, sigma: np.ndarray, run_id: str
) -> Comparison:
    """The laser range of ``target`` against the depth map's range at its pixel.

    ``depth``, ``sigma``: (H, W) float32, metres, z in the left camera. The estimate is
    the median z over the target's window, turned into the range along the centre
    pixel's ray from the laser's aperture (rig profile's rangefinder offset) by
    :func:`rigkit.rangefinder.ranging.range_from_depth`.
    """
    profile = session.rig()
    height, width = depth.shape
    half = target.window_px // 2
    u, v = target.pixel
    cu, cv = round(u), round(v)
    rows = slice(max(cv - half, 0), min(cv + half + 1, height))
    cols = slice(max(cu - half, 0), min(cu + half + 1, width))
    window, window_sigma = depth[rows, cols], sigma[rows, cols]
    finite = np.isfinite(window)
    laser = np.array([r.slope_distance_m for r in target.readings], float)
    laser_range = float(laser.mean()) if laser.size else math.nan
    estimate = sigma_range = math.nan
    if finite.any():
        z = float(np.median(window[finite]))
        z_sigma = float(np.median(window_sigma[finite]))
        estimate = profile_range_from_depth(profile, (width, height), z, (u, v))
        sigma_range = z_sigma * estimate / z
    status = STATUS_OK if finite.any() and laser.size else (
        STATUS_NO_READING if not laser.size else STATUS_NO_ESTIMATE
    )
    error = estimate - laser_range
    return Comparison(
        run_id=run_id,
        time_utc=utc_now(),
        session=session.name,
        target=target.name,
        u=float(u),
        v=float(v),
        window_px=target.window_px,
        laser_range_m=laser_range,
        laser_readings=int(laser.size),
        laser_spread_m=float(laser.std()) if laser.size else math.nan,
        estimate_range_m=estimate,
        estimate_sigma_m=sigma_range,
        valid_fraction=float(finite.mean()),
        error_m=error,
        error_pct=100 * error / laser_range if laser.size else math.nan,
        status=status,
    )


# -- writing results -------------------------------------------------------------------------


def _previews(
    left: np.ndarray,
    depth: np.ndarray,
    sigma: np.ndarray,
    targets: Sequence[Target],
    rows: Sequence[Comparison],
) -> dict[str, np.ndarray]:
    from rigkit.annotate import mark_targets
    from rigkit.preview import colorize, depth_range

    lo, hi = depth_range(depth)
    with np.errstate(invalid="ignore", divide="ignore"):
        relative = 100 * sigma / depth
    grey = np.repeat(np.clip(left, 0, 255).astype(np.uint8)[..., None], 3, axis=2)
    return {
        "depth.png": mark_targets(colorize(depth, lo, hi, "depth z (m)"), depth.shape,
                                  targets, rows),
        "sigma.png": colorize(relative, 0.0, 2.0, "1-sigma error (% of depth)"),
        "left.png": mark_targets(_shrink(grey), depth.shape, targets, rows),
    }


def _shrink(img: np.ndarray) -> np.ndarray:
    import cv2

    from rigkit.preview import PREVIEW_WIDTH

    scale = min(1.0, PREVIEW_WIDTH / img.shape[1])
    if scale == 1.0:
        return img
    size = (round(img.shape[1] * scale), round(img.shape[0] * scale))
    return cv2.resize(img, size, interpolation=cv2.INTER_AREA)


# -- many sessions ---------------------------------------------------------------------------


def safe_process(
    path: Path, run_id: str, force: bool = False, progress: StageReport | None = None
) -> Outcome:
    """:func:`process_session` that turns any failure into a failed Outcome."""
    t0 = time.perf_counter()
    try:
        return process_session(path, run_id, force=force, progress=progress)
    except RigkitError as exc:
        message = str(exc)
    except MemoryError:
        message = "out of memory (process fewer sessions at once: --jobs 1)"
    except Exception as exc:  # a bug must not stop the batch; the trace goes to the log
        message = f"internal error ({type(exc).__name__}: {exc}); please report it"
        _log_failure(path, run_id, message + "\n" + traceback.format_exc())
        return Outcome(path, False, message, time.perf_counter() - t0)
    _log_failure(path, run_id, message)
    return Outcome(path, False, message, time.perf_counter() - t0)


def _log_failure(path: Path, run_id: str, message: str) -> None:
    if is_session(path):
        try:
            detail = message.strip().replace("\n", "\n    ")  # a trace stays indented
            log_event(path, "process", f"run {run_id}: FAILED: {detail}")
        except OSError:
            pass  # a read-only session cannot record its failure; the batch still reports it


def auto_jobs(paths: Sequence[Path], available_bytes: int | None = None) -> int:
    """How many sessions to run at once: bounded by cores and by available memory."""
    largest = max((_session_pixels(p) for p in paths), default=0)
    need = BASE_BYTES + BYTES_PER_PIXEL * largest
    available = available_bytes if available_bytes is not None else _available_memory()
    by_memory = max(1, int(0.8 * available // need))
    return max(1, min(by_memory, os.cpu_count() or 1, len(paths)))


def _session_pixels(path: Path) -> int:
    try:
        frames = load_session(path).frames
    except RigkitError:
        return 0
    return max((f.size_px[0] * f.size_px[1] for f in frames.values()), default=0)


def _available_memory() -> int:
    try:
        with open("/proc/meminfo", encoding="ascii") as handle:
            for line in handle:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except OSError:
        pass
    return int(os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_AVPHYS_PAGES"))


BatchReport = Callable[[Path, str, float], None]


def run_batch(
    paths: Sequence[Path],
    jobs: int,
    *,
    run_id: str | None = None,
    force: bool = False,
    progress: BatchReport | None = None,
    on_done: Callable[[Outcome], None] | None = None,
) -> list[Outcome]:
    """Process sessions, ``jobs`` at a time; outcomes in the order of ``paths``.

    ``progress(session, stage, fraction)`` reports each session's stages;
    ``on_done(outcome)`` is called as each session finishes.
    """
    run_id = run_id or new_run_id()
    report = progress or (lambda path, stage, fraction: None)
    done = on_done or (lambda outcome: None)
    if jobs <= 1 or len(paths) <= 1:
        outcomes = []
        for path in paths:
            outcome = safe_process(path, run_id, force, _for_session(report, path))
            done(outcome)
            outcomes.append(outcome)
        return outcomes
    return _run_parallel(paths, jobs, run_id, force, report, done)


def _for_session(report: BatchReport, path: Path) -> StageReport:
    return lambda stage, fraction: report(path, stage, fraction)


def _run_parallel(
    paths: Sequence[Path],
    jobs: int,
    run_id: str,
    force: bool,
    report: BatchReport,
    done: Callable[[Outcome], None],
) -> list[Outcome]:
    context = multiprocessing.get_context("spawn")
    queue = context.Queue()
    threads = max(1, (os.cpu_count() or 1) // jobs)
    listener = threading.Thread(target=_relay, args=(queue, report), daemon=True)
    listener.start()
    try:
        with ProcessPoolExecutor(
            max_workers=jobs, mp_context=context, initializer=_init_worker,
            initargs=(queue, threads),
        ) as pool:
            futures: dict[Future[Outcome], Path] = {
                pool.submit(_worker_process, path, run_id, force): path for path in paths
            }
            outcomes: dict[Path, Outcome] = {}
            for future in as_completed(futures):
                outcome = _collect(future, futures[future], run_id)
                outcomes[outcome.path] = outcome
                done(outcome)
            return [outcomes[path] for path in paths]
    finally:
        queue.put(None)
        listener.join(timeout=5)


def _collect(future: Future[Outcome], path: Path, run_id: str) -> Outcome:
    """A finished worker's Outcome; a worker that died (e.g. killed for memory) fails
    only its own session."""
    try:
        return future.result()
    except Exception as exc:
        message = f"worker process died ({type(exc).__name__}); out of memory? try --jobs 1"
        _log_failure(path, run_id, message)
        return Outcome(path, False, message, 0.0)


def _relay(queue: Any, report: BatchReport) -> None:
    while (item := queue.get()) is not None:
        report(*item)


_worker_queue: Any = None


def _init_worker(queue: Any, threads: int) -> None:
    import cv2

    global _worker_queue
    _worker_queue = queue
    cv2.setNumThreads(threads)


def _worker_process(path: Path, run_id: str, force: bool) -> Outcome:
    def report(stage: str, fraction: float) -> None:
        _worker_queue.put((path, stage, fraction))

    return safe_process(path, run_id, force, report)
