"""Threads: the same numbers whatever the number of threads, and no more threads than
cores.

**Results independent of the thread count.** A BLAS or LAPACK call that OpenBLAS (or
MKL) splits across threads adds its partial sums in an order set by the number of
threads, so its last bits change with it. In the pipeline those bits are amplified: the
lens fit's least squares moved by 1e-7 relative is a different yaw, a different offset,
and pixels near a validity threshold gain or lose a depth (issue 34: 85 pixels, one by
14.5 m, between ``OPENBLAS_NUM_THREADS=1`` and ``=2`` on the example session). Every
function that computes a result runs inside :func:`serial_blas`, which holds the BLAS
libraries at one thread for as long as any such computation runs, so ``depth.npy`` is
the same bit for bit on one thread or many, in a worker process or on a Dask worker.
The pipeline's matrices are small (a few thousand matches by a few dozen parameters):
one BLAS thread costs nothing measurable and saves the spinning of idle BLAS threads on
a busy machine. OpenCV's parallel loops split images into rows whose results do not
depend on the split; ``tests/pipeline/test_determinism.py`` checks both.

**No oversubscription.** :func:`limit_threads` gives a worker process its share of the
cores for OpenCV and BLAS alike, so that N workers use N cores, not N x cores.

The limits are set through threadpoolctl, which finds every BLAS library loaded into
the process (NumPy's and SciPy's are two different OpenBLAS builds).
"""

from __future__ import annotations

import functools
import os
import threading
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from typing import Any, ParamSpec, TypeVar

import threadpoolctl

_lock = threading.Lock()
_holders = 0
_original: Any = None

P = ParamSpec("P")
R = TypeVar("R")


@contextmanager
def serial_blas() -> Iterator[None]:
    """Run the body with every BLAS library at one thread. Bodies may nest and overlap
    in several threads: each sets one thread as it starts (per-thread BLAS limits, as
    OpenMP builds have, need it), and the last to end restores the limits found by the
    first."""
    global _holders, _original
    with _lock:
        limiter = _as_controller(lambda: threadpoolctl.threadpool_limits(1, user_api="blas"))
        if _holders == 0:
            _original = limiter
        _holders += 1
    try:
        yield
    finally:
        with _lock:
            _holders -= 1
            if _holders == 0:
                _as_controller(_original.restore_original_limits)
                _original = None


def _as_controller(change: Callable[[], R]) -> R:
    """``change()`` run with the right to change OpenBLAS's process-wide limit, which
    threadpoolctl (>= 3.8) gives to one thread at a time, silently ignoring the others:
    rigkit's own changes are serialised by ``_lock``, and the body of a pipeline call may
    run in any thread (a TUI worker, a decoder pool)."""
    controller = getattr(threadpoolctl, "OpenBLASController", None)
    clear = getattr(controller, "clear_controlling_thread", None)
    if clear is not None:
        clear(force=True)
    try:
        return change()
    finally:
        if clear is not None:
            clear(force=True)


def deterministic(function: Callable[P, R]) -> Callable[P, R]:
    """Decorator: ``function`` runs inside :func:`serial_blas`."""

    @functools.wraps(function)
    def wrapper(*args: P.args, **kwargs: P.kwargs) -> R:
        with serial_blas():
            return function(*args, **kwargs)

    return wrapper


def available_cores() -> int:
    """The cores this process may run on (its CPU affinity where the system has one,
    as a container or ``taskset`` sets it; else every core)."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # macOS, Windows
        return max(1, os.cpu_count() or 1)


def limit_threads(threads: int) -> None:
    """Give this process ``threads`` threads for OpenCV's parallel loops and for BLAS,
    for the rest of its life (a worker process's share of the cores)."""
    import cv2

    threads = max(1, int(threads))
    cv2.setNumThreads(threads)
    _as_controller(lambda: threadpoolctl.threadpool_limits(threads, user_api="blas"))
