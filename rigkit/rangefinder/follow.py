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
from rigkit.rangefinder.driver import (
    LineStats,
    PortError,
    Rangefinder,
    ReadTimeout,
    open_rangefinder,
)
from rigkit.rangefinder.framing import RangefinderError, Reading

POLL_S = 0.5
"""Longest wait for a reading before ``stopped`` is checked again, seconds."""
RETRY_S = 2.0
"""Wait between attempts to reopen a lost port, seconds."""
QUIET_S = 10.0
"""Seconds without a reading after which what did arrive is said (as ``rangefinder
read`` says it): frames that never parse are a wrong protocol or a damaged line, not a
working link."""


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
    quiet_s: float = QUIET_S,
    opener: Callable[[str, str], Rangefinder] | None = None,
) -> Iterator[Reading | LinkStatus]:
    """Yield readings from ``url`` and a :class:`LinkStatus` whenever the link changes,
    until ``stopped()`` is true. Errors other than a lost or unopenable port (a device
    refusing a request, a bad frame) are reported as a status and reading goes on; bad
    settings (an unknown protocol) are reported once and end it. Every ``quiet_s``
    seconds without a reading, a status says what arrived meanwhile."""
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
            yield from _readings(device, stopped, poll_s, quiet_s)
        if not stopped():
            _sleep(retry_s, stopped)


def _readings(device: Rangefinder, stopped: Callable[[], bool], poll_s: float,
              quiet_s: float) -> Iterator[Reading | LinkStatus]:
    before, since = device.stats, time.monotonic()
    while not stopped():
        try:
            reading = device.read(timeout=poll_s)
        except ReadTimeout:
            if time.monotonic() - since >= quiet_s:
                seen = device.stats.since(before)
                yield LinkStatus(True, quiet_note(seen, device.protocol.name, quiet_s))
                before, since = device.stats, time.monotonic()
            continue
        except PortError as exc:
            yield LinkStatus(False, f"{exc}; reconnecting")
            return
        except RangefinderError as exc:
            yield LinkStatus(True, str(exc))
        else:
            yield reading
            before, since = device.stats, time.monotonic()


def quiet_note(seen: LineStats, protocol: str, quiet_s: float) -> str:
    """What arrived in ``quiet_s`` seconds without a reading (``seen``, the line's counts
    over them), and what it suggests: frames that never parse, another ``protocol``;
    nothing at all, the trigger or the cable. Said by ``rangefinder log`` and the
    field TUI alike."""
    if seen.frames:
        return (f"no reading in {quiet_s:g} s ({seen.describe()}): not {protocol}? "
                "(check the protocol, the cable and the baud rate)")
    return (f"connected; nothing received in {quiet_s:g} s (fire the laser; if it was "
            "fired, check the cable and the baud rate)")


def _sleep(seconds: float, stopped: Callable[[], bool]) -> None:
    """Sleep up to ``seconds``, waking every 0.1 s to check ``stopped``."""
    deadline = time.monotonic() + seconds
    while not stopped() and time.monotonic() < deadline:
        time.sleep(min(0.1, max(0.0, deadline - time.monotonic())))
