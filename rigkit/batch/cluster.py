"""Processing many sessions on a Dask distributed cluster (``rigkit process
--scheduler tcp://HOST:PORT``): each session is one task, run by
:func:`rigkit.batch.pool.safe_process` on a worker, so the lock, the atomic results and
the per-session outcome are those of the local pool.

The workers read and write the sessions where they lie: every machine must see the
capture folder at the same path (a shared filesystem whose locks work across machines,
such as NFSv4). Only the session's path goes to the scheduler and only its
:class:`~rigkit.batch.session.Outcome` comes back; the frames never pass through it.
Needs the ``cluster`` extra (``pip install 'rigkit[cluster]'``: ``dask[distributed]``).
"""

from __future__ import annotations

import asyncio
from collections.abc import Callable, Sequence
from dataclasses import replace
from pathlib import Path
from types import ModuleType
from typing import Any

from rigkit.batch.pool import log_failure, safe_process
from rigkit.batch.session import Outcome, new_run_id
from rigkit.core.threads import available_cores, limit_threads
from rigkit.errors import InputError

CONNECT_TIMEOUT_S = 5.0
"""How long to try to reach the scheduler before giving up."""
WORKER_WAIT_S = 10.0
"""How long to wait for a first worker to join a reachable scheduler."""


def _distributed() -> ModuleType:
    try:
        import distributed
    except ImportError:
        raise InputError("--scheduler needs Dask distributed: pip install 'rigkit[cluster]'"
                         ) from None
    return distributed


def connect(scheduler: str) -> Any:
    """A ``distributed.Client`` of the scheduler at ``scheduler`` with a worker; InputError
    (one line) when it cannot be reached within :data:`CONNECT_TIMEOUT_S` or no worker
    joins it within :data:`WORKER_WAIT_S`."""
    distributed = _distributed()
    _check_scheduler(scheduler)
    try:
        client = distributed.Client(scheduler, timeout=CONNECT_TIMEOUT_S, set_as_default=False)
    except (OSError, ValueError, TimeoutError) as exc:
        raise InputError(f"--scheduler {scheduler}: cannot reach the scheduler ({exc}); is "
                         "`dask scheduler` running there?") from None
    try:
        client.wait_for_workers(1, timeout=WORKER_WAIT_S)
    except (OSError, TimeoutError):
        client.close()
        raise InputError(f"--scheduler {scheduler}: no worker joined within "
                         f"{WORKER_WAIT_S:g} s (start one: dask worker {scheduler})") from None
    return client


def _check_scheduler(scheduler: str) -> None:
    """InputError (one line) unless a Dask scheduler answers at ``scheduler`` within
    :data:`CONNECT_TIMEOUT_S`: a port that accepts and stays silent, or answers with
    other bytes, is refused here, before a Client could wait on it or parse its bytes."""
    try:
        answer = asyncio.run(asyncio.wait_for(_identity(scheduler), CONNECT_TIMEOUT_S + 1))
    except TimeoutError:
        raise InputError(f"--scheduler {scheduler}: no Dask scheduler answered within "
                         f"{CONNECT_TIMEOUT_S:g} s; is `dask scheduler` running there?"
                         ) from None
    except MemoryError:  # its bytes read as the length of a message no machine holds
        raise InputError(f"--scheduler {scheduler}: answers with bytes that are no Dask "
                         "message; is this a Dask scheduler's port?") from None
    except Exception as exc:  # refused, unreachable, or bytes that are no Dask message
        raise InputError(f"--scheduler {scheduler}: cannot reach the scheduler "
                         f"({type(exc).__name__}: {exc}); is `dask scheduler` running there?"
                         ) from None
    if not isinstance(answer, dict) or answer.get("type") != "Scheduler":
        raise InputError(f"--scheduler {scheduler}: answers, but is not a Dask scheduler")


async def _identity(scheduler: str) -> Any:
    """What the service at ``scheduler`` says it is (Dask's ``identity`` request)."""
    from distributed.comm import connect as open_comm

    comm = await open_comm(scheduler, timeout=CONNECT_TIMEOUT_S)
    try:
        await comm.write({"op": "identity", "reply": True})
        return await comm.read()
    finally:
        comm.abort()


def run_on_cluster(
    paths: Sequence[Path],
    client: Any,
    *,
    run_id: str | None = None,
    force: bool = False,
    on_done: Callable[[Outcome], None] | None = None,
) -> list[Outcome]:
    """Process sessions as tasks on the cluster of ``client`` (from :func:`connect`);
    outcomes in the order of ``paths``, carrying the paths as given. ``on_done(outcome)``
    is called as each task completes. A task lost with its worker fails only its own
    session."""
    distributed = _distributed()
    run_id = run_id or new_run_id()
    done = on_done or (lambda outcome: None)
    sharing = _threads_per_host(client)
    futures = {
        client.submit(_process_task, path.absolute(), run_id, force, sharing, pure=False,
                      key=f"rigkit-process-{run_id}-{i}"): path
        for i, path in enumerate(paths)
    }
    outcomes: dict[Path, Outcome] = {}
    for future in distributed.as_completed(futures, loop=client.loop):
        path = futures[future]
        outcome = replace(_result(future, path, run_id), path=path)
        outcomes[path] = outcome
        done(outcome)
    return [outcomes[path] for path in paths]


def _threads_per_host(client: Any) -> dict[str, int]:
    """How many tasks the cluster's workers on each host run at once (their threads)."""
    hosts: dict[str, int] = {}
    for worker in client.scheduler_info().get("workers", {}).values():
        hosts[worker["host"]] = hosts.get(worker["host"], 0) + int(worker["nthreads"])
    return hosts


def _process_task(path: Path, run_id: str, force: bool, sharing: dict[str, int]) -> Outcome:
    """:func:`safe_process` on a worker, with OpenCV and BLAS given the task's share of
    the host's cores (its cores over the tasks its workers run at once), so that a
    host's workers use its cores once, not once per task."""
    worker = _distributed().get_worker()
    tasks = sharing.get(worker.ip) or worker.state.nthreads
    limit_threads(max(1, available_cores() // max(1, tasks)))
    outcome = safe_process(path, run_id, force)
    if outcome.ok:
        return outcome
    return replace(outcome, message=f"{outcome.message} (on worker {worker.address}, "
                                    "with the path as that worker sees it)")


def _result(future: Any, path: Path, run_id: str) -> Outcome:
    """A finished task's Outcome, or a failed one when the task itself failed (its
    worker died, rigkit missing on the worker, ...)."""
    try:
        outcome: Outcome = future.result()
        return outcome
    except Exception as exc:
        message = f"task failed on the cluster ({type(exc).__name__}: {exc})"
        log_failure(path, run_id, message)
        return Outcome(path, False, message, 0.0)
