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
import sys
import threading
from collections.abc import Callable, Iterable, Iterator
from concurrent.futures import Future, ThreadPoolExecutor
from contextlib import contextmanager
from typing import Any, ParamSpec, TypeVar

import threadpoolctl

from rigkit.core.lazy import load

_lock = threading.Lock()
_holders = 0
_limiters: list[Any] = []  # the limits each body set, undone in reverse by the last
_modules_seen = 0  # len(sys.modules) when the libraries were last found
_libraries: Any = None

P = ParamSpec("P")
R = TypeVar("R")


BLAS_CARRIERS = ("scipy.linalg",)
"""Modules whose import loads a BLAS library of its own (SciPy's OpenBLAS, beside NumPy's):
imported by :func:`deterministic` before its body begins. The pipeline imports SciPy when
it first calls it (:func:`rigkit.core.lazy.function`), and a library first loaded inside a
body would run at its own thread count, its last bits set by the machine's cores."""


@contextmanager
def serial_blas() -> Iterator[None]:
    """Run the body with every BLAS library at one thread. Bodies may nest and overlap
    in several threads: each sets one thread as it starts (per-thread BLAS limits, as
    OpenMP builds have, need it), and the last to end restores the limits found before.
    The libraries are found when the first body begins, and again when one begins after
    a module was imported (a library loaded by a body that is still running): finding
    them takes ~1 ms (every library loaded is looked at), and a pipeline run starts some
    40 bodies, its stages and their threads' tasks."""
    global _holders, _libraries, _modules_seen
    with _lock:
        if _holders == 0 or len(sys.modules) != _modules_seen:
            _libraries = threadpoolctl.ThreadpoolController()
            _modules_seen = len(sys.modules)
        _limiters.append(_as_controller(lambda: _libraries.limit(limits=1, user_api="blas")))
        _holders += 1
    try:
        yield
    finally:
        with _lock:
            _holders -= 1
            if _holders == 0:  # each library back to the limit it had before any body
                for limiter in reversed(_limiters):
                    _as_controller(limiter.restore_original_limits)
                _limiters.clear()


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
    """Decorator: ``function`` runs inside :func:`serial_blas`, with the libraries that
    bring their own BLAS (``BLAS_CARRIERS``) imported first."""

    @functools.wraps(function)
    def wrapper(*args: P.args, **kwargs: P.kwargs) -> R:
        for name in BLAS_CARRIERS:
            load(name)
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


def view_threads() -> int:
    """Threads for a pipeline's independent per-view work (the right and the back
    view's matching, the two views' agreement, the chunks of one image): as many as
    OpenCV's parallel loops may use, which :func:`limit_threads` sets to a worker
    process's share of the cores (1: everything runs in the calling thread)."""
    import cv2

    return max(1, int(cv2.getNumThreads()))


class ViewPool:
    """A pool of :func:`view_threads` threads for independent pieces of one result.

    Each task runs inside :func:`serial_blas`, and its result is what it would be in
    the calling thread: the pool only overlaps work that does not depend on one
    another (OpenCV and NumPy release the GIL in their loops). Tasks are collected in
    the order the caller chooses, never in the order they finish, so nothing that adds
    up partial results depends on the number of threads. With one thread a task runs
    at once, in the calling thread, when it is submitted.

    Use as a context manager; leaving it waits for the tasks still running (and drops
    those not started, where an error left the block)."""

    def __init__(self, threads: int | None = None) -> None:
        self.threads = view_threads() if threads is None else max(1, threads)
        self._pool: ThreadPoolExecutor | None = (
            ThreadPoolExecutor(self.threads, thread_name_prefix="rigkit-view")
            if self.threads > 1 else None
        )

    def submit(self, function: Callable[P, R], *args: P.args, **kwargs: P.kwargs
               ) -> Future[R]:
        """``function(*args, **kwargs)`` as a future: in a pool thread, or (one thread)
        run now with its result or exception held in the future."""
        task = deterministic(function)
        if self._pool is not None:
            return self._pool.submit(task, *args, **kwargs)
        done: Future[R] = Future()
        try:
            done.set_result(task(*args, **kwargs))
        except BaseException as exc:  # held for .result(), as a pool's future holds it
            done.set_exception(exc)
        return done

    def map(self, function: Callable[..., R], *iterables: Iterable[Any]) -> list[R]:
        """``[function(*args) for args in zip(*iterables)]`` with the calls spread over
        the pool; the first call's exception (in order) is raised."""
        futures = [self.submit(function, *args) for args in zip(*iterables, strict=True)]
        return [f.result() for f in futures]

    def __enter__(self) -> ViewPool:
        return self

    def __exit__(self, *exc: object) -> None:
        if self._pool is not None:
            self._pool.shutdown(wait=True, cancel_futures=True)
