"""rigkit.core.chatter: what C code prints to descriptor 2 is captured, and a complaint
printed while captures ran side by side is only ever given to the call that made it."""

from __future__ import annotations

import os
import threading

from rigkit.core.chatter import attributed, captured_stderr


def test_an_exclusive_capture_holds_only_its_own_text() -> None:
    with captured_stderr() as chatter:
        os.write(2, b"libpng warning: something\n")
    assert chatter.text == "libpng warning: something\n"
    assert not chatter.shared


def test_side_by_side_complaints_go_to_the_call_that_printed_them() -> None:
    both_in = threading.Barrier(2, timeout=5)
    runs = {"bad": 0, "good": 0}
    results: dict[str, tuple[str, str]] = {}

    def call(name: str) -> str:
        runs[name] += 1
        if runs[name] == 1:
            both_in.wait()  # the first runs overlap
        if name == "bad":
            os.write(2, b"Premature end of JPEG file\n")
        if runs[name] == 1:
            both_in.wait()  # and end together: each capture saw the other's output
        return name

    def worker(name: str) -> None:
        results[name] = attributed(lambda: call(name), lambda text: "Premature" in text)

    threads = [threading.Thread(target=worker, args=(n,)) for n in ("bad", "good")]
    for t in threads:
        t.start()
    for t in threads:
        t.join(10)
    assert results["good"] == ("good", "")  # run again alone: nothing of its own
    assert results["bad"] == ("bad", "Premature end of JPEG file\n")
    assert runs == {"bad": 2, "good": 2}


def test_a_shared_capture_alone_is_not_run_again() -> None:
    calls = []

    def call() -> int:
        calls.append(1)
        os.write(2, b"Premature end of JPEG file\n")
        return 7

    assert attributed(call, lambda text: "Premature" in text) == (
        7, "Premature end of JPEG file\n")
    assert len(calls) == 1
