"""Batch processing of capture sessions: one session (lock, depth, laser comparisons,
results swapped in as a whole) and a pool of worker processes for many."""

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
