"""Following a rangefinder for as long as someone wants readings, across lost links.

:func:`follow` opens the port, yields every reading as it arrives and, when the cable is
pulled or the Bluetooth link drops, says so and keeps trying to open the port again
until it comes back. It blocks (run it in a worker thread) but returns to check
``stopped`` at least every ``poll_s`` seconds, so a caller can end it promptly.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass

from rigkit.errors import InputError
from rigkit.rangefinder.driver import PortError, Rangefinder, ReadTimeout, open_rangefinder
from rigkit.rangefinder.framing import RangefinderError, Reading

POLL_S = 0.5
"""Longest wait for a reading before ``stopped`` is checked again, seconds."""
RETRY_S = 2.0
"""Wait between attempts to reopen a lost port, seconds."""


@dataclass(frozen=True)
class LinkStatus:
    """The link's state for people: ``connected`` or not, and a one-line ``message``."""

    connected: bool
    message: str


def follow(
    url: str,
    protocol: str = "trupulse",
    *,
    stopped: Callable[[], bool],
    poll_s: float = POLL_S,
    retry_s: float = RETRY_S,
    opener: Callable[[str, str], Rangefinder] | None = None,
) -> Iterator[Reading | LinkStatus]:
    """Yield readings from ``url`` and a :class:`LinkStatus` whenever the link changes,
    until ``stopped()`` is true. Errors other than a lost or unopenable port (a device
    refusing a request, a bad frame) are reported as a status and reading goes on; bad
    settings (an unknown protocol) are reported once and end it."""
    open_port = opener or (lambda u, p: open_rangefinder(u, p, timeout=poll_s))
    while not stopped():
        try:
            device = open_port(url, protocol)
        except RangefinderError as exc:
            yield LinkStatus(False, f"{exc}; retrying every {retry_s:g} s")
            _sleep(retry_s, stopped)
            continue
        except InputError as exc:  # bad settings: trying again cannot help
            yield LinkStatus(False, str(exc))
            return
        yield LinkStatus(True, f"connected to {url} ({protocol})")
        with device:
            yield from _readings(device, stopped, poll_s)
        if not stopped():
            _sleep(retry_s, stopped)


def _readings(device: Rangefinder, stopped: Callable[[], bool], poll_s: float
              ) -> Iterator[Reading | LinkStatus]:
    while not stopped():
        try:
            yield device.read(timeout=poll_s)
        except ReadTimeout:
            continue
        except PortError as exc:
            yield LinkStatus(False, f"{exc}; reconnecting")
            return
        except RangefinderError as exc:
            yield LinkStatus(True, str(exc))


def _sleep(seconds: float, stopped: Callable[[], bool]) -> None:
    """Sleep up to ``seconds``, waking every 0.1 s to check ``stopped``."""
    deadline = time.monotonic() + seconds
    while not stopped() and time.monotonic() < deadline:
        time.sleep(min(0.1, max(0.0, deadline - time.monotonic())))
