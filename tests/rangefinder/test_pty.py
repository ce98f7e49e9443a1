"""Integration: the driver on a real pseudo-terminal served by the simulator."""

from __future__ import annotations

import os
import time

import pytest

from rigkit.rangefinder import DeviceError, PortError, ReadTimeout, open_rangefinder
from rigkit.rangefinder.sim import PtySimulator, SimConfig

pytestmark = pytest.mark.skipif(not hasattr(os, "openpty"), reason="needs a POSIX pty")


def test_reads_trupulse_shots_over_a_pty() -> None:
    with PtySimulator(SimConfig(interval=0.02, distance=234.0, unit="F")) as sim:
        assert sim.path.startswith("/dev/")
        with open_rangefinder(sim.path, "trupulse", timeout=2) as rf:
            readings = [rf.read() for _ in range(3)]
    assert all(r.unit == "ft" and abs(r.slope_distance_m - 234.0) < 0.05 for r in readings)
    assert not sim.running


def test_trigger_goes_down_the_line_and_the_shot_comes_back() -> None:
    with PtySimulator(SimConfig(interval=0)) as sim, open_rangefinder(sim.path, timeout=0.3) as rf:
        with pytest.raises(ReadTimeout):
            rf.read()  # nobody pulls the trigger
        assert rf.read(trigger=True).slope_distance_m == pytest.approx(302.0)


def test_vectronix_request_response_over_a_pty() -> None:
    config = SimConfig(device="vectronix", distance=292.0)
    with PtySimulator(config) as sim, open_rangefinder(sim.path, "vectronix", timeout=2) as rf:
        assert rf.read().slope_distance_m == pytest.approx(292.0)
        assert rf.read().slope_distance_m == pytest.approx(292.0)


def test_noisy_line_over_a_pty() -> None:
    config = SimConfig(interval=0.01, garbage=0.6, bad_checksum=0.3, seed=11)
    with PtySimulator(config) as sim, open_rangefinder(sim.path, timeout=3) as rf:
        readings = [rf.read() for _ in range(5)]
        stats = rf.stats
    assert all(r.slope_distance_m == pytest.approx(302.0) for r in readings)
    assert stats.bad_checksums + stats.malformed > 0


def test_silent_pty_times_out() -> None:
    with (
        PtySimulator(SimConfig(silent=True, interval=0.01)) as sim,
        open_rangefinder(sim.path, timeout=0.3) as rf,
        pytest.raises(ReadTimeout, match=f"no reading from {sim.path} within 0.3 s"),
    ):
        rf.read()


def test_pulled_cable_over_a_pty_releases_the_port() -> None:
    with PtySimulator(SimConfig(interval=0.02, disconnect_after=1)) as sim:
        rf = open_rangefinder(sim.path, timeout=2)
        rf.read()
        with pytest.raises(PortError, match=f"lost connection to {sim.path}: .*port closed"):
            rf.read()
        assert rf.closed
        assert not rf.port.is_open  # type: ignore[attr-defined]
        deadline = time.monotonic() + 2
        while sim.running and time.monotonic() < deadline:
            time.sleep(0.01)
        assert not sim.running


def test_second_program_on_the_same_port_is_refused() -> None:
    with PtySimulator(SimConfig(interval=0)) as sim, open_rangefinder(sim.path, timeout=1):
        with pytest.raises(PortError, match="in use by another program"):
            open_rangefinder(sim.path)


def test_vectronix_rejection_over_a_pty_is_a_device_error() -> None:
    config = SimConfig(device="vectronix", miss=1.0)
    with (
        PtySimulator(config) as sim,
        open_rangefinder(sim.path, "vectronix", timeout=2) as rf,
        pytest.raises(DeviceError, match="no valid range"),
    ):
        rf.read()
