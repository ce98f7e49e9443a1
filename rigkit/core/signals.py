"""SIGTERM as an interruption: where a command stages output that a plain SIGTERM would
leave behind (``rigkit export``'s staging folders), :func:`terminate_as_interrupt`
makes SIGTERM raise :class:`Terminated`, a KeyboardInterrupt, so that every cleanup
that Ctrl-C runs runs for it too, and the command line exits with status 143."""

from __future__ import annotations

import contextlib
import signal
import threading
from collections.abc import Iterator


class Terminated(KeyboardInterrupt):
    """SIGTERM, raised where the command is."""


def _raise_terminated(signum: int, frame: object) -> None:
    raise Terminated


@contextlib.contextmanager
def terminate_as_interrupt() -> Iterator[None]:
    """SIGTERM raises :class:`Terminated` for the body (main thread only; elsewhere the
    body runs as it is), and the previous handler is restored after it."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = signal.signal(signal.SIGTERM, _raise_terminated)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, previous)
