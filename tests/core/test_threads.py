"""rigkit.core.threads: one BLAS thread while any result is computed, the caller's
limits back afterwards, also when bodies overlap in several threads."""

from __future__ import annotations

import threading

import numpy as np
import pytest
from threadpoolctl import threadpool_info, threadpool_limits

from rigkit.core.threads import ViewPool, deterministic, serial_blas


def _blas_threads() -> set[int]:
    np.dot(np.ones(2), np.ones(2))  # NumPy's BLAS is loaded
    return {i["num_threads"] for i in threadpool_info() if i["user_api"] == "blas"}


def test_serial_blas_holds_one_thread_and_restores_the_callers() -> None:
    with threadpool_limits(limits=2, user_api="blas"):
        with serial_blas():
            assert _blas_threads() == {1}
            with serial_blas():  # nested
                assert _blas_threads() == {1}
            assert _blas_threads() == {1}
        assert _blas_threads() == {2}


def test_overlapping_bodies_in_threads_keep_one_thread_until_the_last_ends() -> None:
    first_in, second_in, first_out = threading.Event(), threading.Event(), threading.Event()
    seen: list[set[int]] = []

    def first() -> None:
        with serial_blas():
            first_in.set()
            second_in.wait(5)
        first_out.set()

    def second() -> None:
        first_in.wait(5)
        with serial_blas():
            second_in.set()
            first_out.wait(5)
            seen.append(_blas_threads())  # the first body has ended, this one has not

    with threadpool_limits(limits=2, user_api="blas"):
        threads = [threading.Thread(target=f) for f in (first, second)]
        for t in threads:
            t.start()
        for t in threads:
            t.join(10)
        assert seen == [{1}]
        assert _blas_threads() == {2}


def test_deterministic_keeps_the_functions_name_and_result() -> None:
    @deterministic
    def blas_threads() -> set[int]:
        """Docstring."""
        return _blas_threads()

    with threadpool_limits(limits=2, user_api="blas"):
        assert blas_threads() == {1}
    assert blas_threads.__name__ == "blas_threads" and blas_threads.__doc__ == "Docstring."


def test_a_view_pool_of_one_runs_each_task_at_once_in_the_calling_thread() -> None:
    ran: list[str] = []
    with ViewPool(1) as pool:
        first = pool.submit(lambda: ran.append(threading.current_thread().name) or 1)
        assert ran == [threading.current_thread().name]  # before .result() is asked
        failed = pool.submit(lambda: 1 // 0)
    assert first.result() == 1
    with pytest.raises(ZeroDivisionError):
        failed.result()


def test_a_view_pools_tasks_hold_one_blas_thread_and_come_back_in_order() -> None:
    with threadpool_limits(limits=2, user_api="blas"), ViewPool(2) as pool:
        assert pool.map(lambda k: (k, _blas_threads()), range(4)) == [(k, {1}) for k in range(4)]
        with pytest.raises(ValueError, match="first"):  # the first error in order
            pool.map(lambda k: (_ for _ in ()).throw(ValueError(("second", "first")[k < 2])),
                     range(4))


def test_a_blas_library_imported_while_a_body_runs_is_held_too() -> None:
    """SciPy is imported when the pipeline first calls it (rigkit.core.lazy.function),
    possibly while another body runs (a frame decoding in a pool): a deterministic
    function imports it before its body begins, and the body finds it, so its OpenBLAS
    runs at one thread there as NumPy's does; the last body's end gives every library
    back its own limit. A fresh interpreter, where nothing has imported SciPy yet."""
    import json
    import os
    import subprocess
    import sys

    probe = """
import json, sys
import numpy
from threadpoolctl import threadpool_info
from rigkit.core.threads import deterministic, serial_blas

def blas():
    return [i["num_threads"] for i in threadpool_info() if i["user_api"] == "blas"]

@deterministic
def fit():
    import scipy.linalg
    return blas()

default = blas()[0]
assert "scipy" not in sys.modules
with serial_blas():  # a body already running
    inside = fit()
print(json.dumps({"default": default, "inside": inside, "after": blas()}))
"""
    # Each library at its own default, as a user's shell leaves it.
    env = {k: v for k, v in os.environ.items() if not k.endswith("_NUM_THREADS")}
    out = json.loads(subprocess.run([sys.executable, "-c", probe], capture_output=True,
                                    text=True, check=True, timeout=120, env=env).stdout)
    assert len(out["inside"]) >= 2 and set(out["inside"]) == {1}  # NumPy's and SciPy's
    assert set(out["after"]) == {out["default"]}
