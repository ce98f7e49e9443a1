"""rigkit.core.threads: one BLAS thread while any result is computed, the caller's
limits back afterwards, also when bodies overlap in several threads."""

from __future__ import annotations

import threading

import numpy as np
from threadpoolctl import threadpool_info, threadpool_limits

from rigkit.core.threads import deterministic, serial_blas


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
