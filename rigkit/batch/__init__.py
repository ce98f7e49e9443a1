"""Batch processing of capture sessions: one session (lock, depth, laser comparisons,
results swapped in as a whole) and a pool of worker processes for many.

Its public names are imported on first use (:mod:`rigkit.core.lazy`).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from rigkit.core.lazy import exports

if TYPE_CHECKING:
    from rigkit.batch.compare import compare_target
    from rigkit.batch.pool import auto_jobs, run_batch, safe_process
    from rigkit.batch.session import Outcome, new_run_id, process_session

__all__ = [
    "Outcome",
    "auto_jobs",
    "compare_target",
    "new_run_id",
    "process_session",
    "run_batch",
    "safe_process",
]

__getattr__ = exports(__name__, {
    "Outcome": "session",
    "auto_jobs": "pool",
    "compare_target": "compare",
    "new_run_id": "session",
    "process_session": "session",
    "run_batch": "pool",
    "safe_process": "pool",
})
