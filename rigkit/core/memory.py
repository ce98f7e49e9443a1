"""How the process gets memory for image-sized arrays.

The pipeline makes many short-lived arrays the size of a 16 MP image (64 MB in float32,
128 MB in float64). Two defaults make each of them cost more than its arithmetic:

- glibc's allocator hands every request above its mmap threshold (32 MB at most, by
  default) to the kernel as fresh pages and returns them on free, so each such array
  is faulted in page by page again. Raising the threshold above any array rigkit
  makes, and the trim threshold with it, lets a freed block serve the next request of
  its size (what ``MALLOC_MMAP_THRESHOLD_`` and ``MALLOC_TRIM_THRESHOLD_`` do from the
  environment; mallopt(3)). The peak is unchanged, since the same arrays are alive at
  once; the process keeps its peak until it exits. Threads share one heap (one
  malloc arena, ``M_ARENA_MAX``): glibc otherwise gives each thread that allocates
  (rigkit's per-view threads, :class:`rigkit.core.threads.ViewPool`) a heap of its
  own, and a block freed in one cannot serve the next request in another (the depth
  command's peak was 1.12 GB with per-thread heaps, 0.94 GB with one).
- NumPy asks the kernel for transparent huge pages for large arrays
  (``madvise(MADV_HUGEPAGE)``), and where the kernel compacts memory to find them on
  a page fault (``/sys/kernel/mm/transparent_hugepage/defrag`` set to ``madvise``, a
  common default) a fault can stall for tens of milliseconds: on the 2-core machine
  rigkit is benchmarked on, a fresh 64 MB array took 12-145 ms with huge pages and a
  steady 22 ms without (what ``NUMPY_MADVISE_HUGEPAGE=0`` does from the environment).

Together they took ~1.4 s off the 7.5 s of ``rigkit depth`` on a full-resolution
triple, process start to exit (docs/results-log.md, "Memory for image-sized arrays").
:func:`tune_for_images` sets both from inside, so that every way of starting rigkit
gets them; it is for the ``rigkit`` command and the benchmarks, not for a library
import to do to its host process.
"""

from __future__ import annotations

import ctypes
import importlib
from typing import NamedTuple

_M_TRIM_THRESHOLD = -1
_M_MMAP_THRESHOLD = -3
_M_ARENA_MAX = -8
KEEP_BYTES = 1 << 30
"""Blocks up to this size (1 GiB: any array of a 16 MP image, in any dtype) come from,
and go back to, the process's own heap."""


class Tuned(NamedTuple):
    """What :func:`tune_for_images` could set: freed blocks reused (glibc only), and
    NumPy's huge-page advice off (NumPy versions that have the switch)."""

    reuse_freed: bool
    no_huge_pages: bool


def tune_for_images() -> Tuned:
    """Set the process's allocation for image-sized arrays (see the module's
    docstring). Call once, early in the process."""
    return Tuned(_reuse_freed_blocks(), _no_huge_page_advice())


def _reuse_freed_blocks() -> bool:
    try:
        mallopt = ctypes.CDLL(None).mallopt  # the C library the process already has
    except (OSError, AttributeError, TypeError):  # not glibc, or no C library to ask
        return False
    mallopt.argtypes = (ctypes.c_int, ctypes.c_int)
    return bool(mallopt(_M_MMAP_THRESHOLD, KEEP_BYTES)) and bool(
        mallopt(_M_TRIM_THRESHOLD, KEEP_BYTES)
    ) and bool(mallopt(_M_ARENA_MAX, 1))


def _no_huge_page_advice() -> bool:
    # NumPy's run-time switch for its madvise (numpy._core from 2.0, numpy.core before).
    for name in ("numpy._core.multiarray", "numpy.core.multiarray"):
        try:
            switch = importlib.import_module(name)._set_madvise_hugepage
        except (ImportError, AttributeError):
            continue
        switch(False)
        return True
    return False
