"""Following a rangefinder across lost links (rigkit.rangefinder.follow), on the simulator."""

from __future__ import annotations

import itertools

import pytest

from rigkit.rangefinder import PortError, open_rangefinder
from rigkit.rangefinder.follow import LinkStatus, follow
from rigkit.rangefinder.framing import Reading


def _take(url: str, n: int, **options: object) -> list[Reading | LinkStatus]:
    items: list[Reading | LinkStatus] = []
    for item in follow(url, stopped=lambda: len(items) >= n, poll_s=0.2, retry_s=0.05,
                       **options):  # type: ignore[arg-type]
        items.append(item)
    return items


def test_readings_arrive_after_the_link_is_up() -> None:
    items = _take("sim://trupulse?interval=0.02&distance=250", 3)
    assert isinstance(items[0], LinkStatus) and items[0].connected
    assert [round(r.slope_distance_m) for r in items[1:]] == [250, 250]


def test_a_pulled_cable_is_reported_and_the_link_comes_back() -> None:
    items = _take("sim://trupulse?interval=0.02&disconnect_after=1", 6)
    kinds = [("up" if i.connected else "down") if isinstance(i, LinkStatus) else "reading"
             for i in items]
    assert kinds == ["up", "reading", "down", "up", "reading", "down"]
    assert "reconnecting" in items[2].message  # type: ignore[union-attr]


def test_a_port_that_does_not_open_is_retried() -> None:
    calls = itertools.count()

    def opener(url: str, protocol: str):  # fails twice, then opens the simulator
        if next(calls) < 2:
            raise PortError(f"cannot open {url}: no such device")
        return open_rangefinder("sim://trupulse?interval=0.02", protocol, timeout=0.2)

    items = _take("/dev/rfcomm9", 4, opener=opener)
    assert [isinstance(i, LinkStatus) and i.connected for i in items[:3]] == \
        [False, False, True]
    assert "no such device; retrying" in items[0].message  # type: ignore[union-attr]
    assert isinstance(items[3], Reading)


def test_stopping_ends_it_promptly() -> None:
    import time

    start = time.monotonic()
    items = list(follow("sim://trupulse?silent=1", stopped=lambda: time.monotonic() - start > 0.3,
                        poll_s=0.1))
    assert time.monotonic() - start < 1.0
    assert len(items) == 1 and isinstance(items[0], LinkStatus)


@pytest.mark.parametrize("url", ["sim://nothing"])
def test_bad_settings_are_reported_not_raised(url: str) -> None:
    items = _take(url, 1)
    assert isinstance(items[0], LinkStatus) and not items[0].connected


def test_an_unknown_protocol_is_reported_once() -> None:
    items = list(follow("sim://trupulse", "morse", stopped=lambda: False))
    assert len(items) == 1 and not items[0].connected  # type: ignore[union-attr]
    assert "morse" in items[0].message  # type: ignore[union-attr]


@pytest.mark.parametrize("options, said", [
    ("bad_checksum=1&interval=0.05", "bad checksums): not trupulse?"),
    ("silent=1", "connected; nothing received in 0.6 s (fire the laser"),
])
def test_a_link_that_gives_no_reading_says_what_arrives(options: str, said: str) -> None:
    """Before: frames that never parsed (or nothing at all) left "connected" standing
    for as long as the operator waited."""
    items: list[Reading | LinkStatus] = []
    for item in follow(f"sim://trupulse?{options}", stopped=lambda: len(items) >= 3,
                       poll_s=0.2, retry_s=0.05, quiet_s=0.6):
        items.append(item)
    notes = [i.message for i in items[1:] if isinstance(i, LinkStatus)]
    assert notes and all(said in note for note in notes)
    assert not any(isinstance(i, Reading) for i in items)
