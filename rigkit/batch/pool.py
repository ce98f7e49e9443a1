"""Processing many sessions: in parallel worker processes with memory-bounded
concurrency, one failing session never stopping the others."""

from __future__ import annotations

import contextlib
import ctypes
import multiprocessing
import os
import signal
import sys
import threading
import time
import traceback
from collections.abc import Callable, Sequence
from concurrent.futures import Future, ProcessPoolExecutor, as_completed
from pathlib import Path
from typing import Any

from rigkit.batch.session import Outcome, StageReport, new_run_id, process_session
from rigkit.capture.session import is_session, load_session, log_event
from rigkit.core.threads import available_cores, limit_threads
from rigkit.errors import RigkitError, environment_message

#: Memory a session needs, per pixel of one frame, at the peak of decoding and the
#: pipeline (measured by benchmarks/bench_process.py), plus a fixed overhead.
BYTES_PER_PIXEL = 130
BASE_BYTES = 400 * 2**20


def safe_process(
    path: Path, run_id: str, force: bool = False, progress: StageReport | None = None
) -> Outcome:
    """:func:`process_session` that turns any failure into a failed Outcome."""
    t0 = time.perf_counter()
    try:
        return process_session(path, run_id, force=force, progress=progress)
    except RigkitError as exc:
        message = str(exc)
    except OSError as exc:  # a full disk, a read-only session: the machine's, not a bug
        message = environment_message(exc)
    except MemoryError:
        message = "out of memory (process fewer sessions at once: --jobs 1)"
    except Exception as exc:  # a bug must not stop the batch; the trace goes to the log
        message = f"internal error ({type(exc).__name__}: {exc}); please report it"
        log_failure(path, run_id, message + "\n" + traceback.format_exc())
        return Outcome(path, False, message, time.perf_counter() - t0)
    log_failure(path, run_id, message)
    return Outcome(path, False, message, time.perf_counter() - t0)


def log_failure(path: Path, run_id: str, message: str) -> None:
    """Record a failed run in the session's ``history.log`` where it can be written."""
    if is_session(path):
        try:
            detail = message.strip().replace("\n", "\n    ")  # a trace stays indented
            log_event(path, "process", f"run {run_id}: FAILED: {detail}")
        except (OSError, RigkitError):  # read-only, or its log a link: the batch still says it
            pass


def auto_jobs(paths: Sequence[Path], available_bytes: int | None = None) -> int:
    """How many sessions to run at once: bounded by cores and by available memory."""
    largest = max((_session_pixels(p) for p in paths), default=0)
    need = BASE_BYTES + BYTES_PER_PIXEL * largest
    available = available_bytes if available_bytes is not None else _available_memory()
    by_memory = max(1, int(0.8 * available // need))
    return max(1, min(by_memory, available_cores(), len(paths)))


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
    threads = max(1, available_cores() // jobs)
    listener = threading.Thread(target=_relay, args=(queue, report), daemon=True)
    listener.start()
    try:
        with ProcessPoolExecutor(
            max_workers=jobs, mp_context=context, initializer=_init_worker,
            initargs=(queue, threads, os.getpid()),
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
        log_failure(path, run_id, message)
        return Outcome(path, False, message, 0.0)


def _relay(queue: Any, report: BatchReport) -> None:
    while (item := queue.get()) is not None:
        report(*item)


_worker_queue: Any = None
_PR_SET_PDEATHSIG = 1  # <linux/prctl.h>


def _init_worker(queue: Any, threads: int, parent: int) -> None:
    global _worker_queue
    _worker_queue = queue
    limit_threads(threads)  # N workers on N cores, not N x cores
    _die_with(parent)


def _die_with(parent: int) -> None:
    """End this worker when the process ``parent`` that started it dies (``kill -9``
    of ``rigkit process``): otherwise it finishes its session and then blocks for ever
    on the progress queue nobody reads. Linux delivers SIGKILL on the parent's death
    (prctl PR_SET_PDEATHSIG); elsewhere a thread polls the parent id once a second."""
    if sys.platform.startswith("linux"):
        with contextlib.suppress(OSError, AttributeError):
            ctypes.CDLL(None, use_errno=True).prctl(_PR_SET_PDEATHSIG, signal.SIGKILL)
    if os.getppid() != parent:  # died before the request was made
        os._exit(1)

    def watch() -> None:
        while os.getppid() == parent:
            time.sleep(1.0)
        os._exit(1)

    threading.Thread(target=watch, daemon=True, name="parent-watch").start()


def _worker_process(path: Path, run_id: str, force: bool) -> Outcome:
    def report(stage: str, fraction: float) -> None:
        _worker_queue.put((path, stage, fraction))

    return safe_process(path, run_id, force, report)
