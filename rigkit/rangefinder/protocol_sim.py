"""pyserial URL handler for ``sim://<device>?key=value&...`` (a simulated rangefinder).

pyserial finds this module because importing :mod:`rigkit.rangefinder` adds
that package to ``serial.protocol_handler_packages``; then
``serial.serial_for_url("sim://trupulse?interval=0.2")`` returns a port whose
far end is a :class:`~rigkit.rangefinder.sim.SimulatedDevice` running on the
monotonic clock. Options are listed in :data:`rigkit.rangefinder.sim.SIM_OPTIONS`.
Baud rate and framing are accepted and ignored. After a simulated cable pull,
reads and writes raise ``SerialException`` like a real unplugged adapter.
"""

from __future__ import annotations

import time

from serial.serialutil import PortNotOpenError, SerialBase, SerialException

from rigkit.errors import InputError
from rigkit.rangefinder.sim import SimulatedDevice, make_device, parse_sim_url

_DISCONNECTED = "device disconnected (simulated cable pull)"


class Serial(SerialBase):
    """A serial port whose other end is a simulated rangefinder."""

    is_open: bool

    def __init__(self, *args: object, **kwargs: object) -> None:
        self._device: SimulatedDevice | None = None
        self._rx = bytearray()
        super().__init__(*args, **kwargs)

    def open(self) -> None:
        if self.is_open:
            raise SerialException("port is already open")
        if self._port is None:
            raise SerialException("port must be configured before it can be used")
        try:
            config = parse_sim_url(self._port)
        except InputError as exc:
            raise SerialException(str(exc)) from None
        self._device = make_device(config, time.monotonic())
        self._rx.clear()
        self.is_open = True

    def close(self) -> None:
        self.is_open = False
        self._device = None

    def _reconfigure_port(self) -> None:
        """Nothing to configure on a simulated line."""

    def _live(self) -> SimulatedDevice:
        if not self.is_open or self._device is None:
            raise PortNotOpenError()
        return self._device

    def _collect(self) -> SimulatedDevice:
        device = self._live()
        self._rx += device.output(time.monotonic())
        if device.disconnected and not self._rx:
            raise SerialException(_DISCONNECTED)
        return device

    @property
    def in_waiting(self) -> int:
        self._collect()
        return len(self._rx)

    def read(self, size: int = 1) -> bytes:
        deadline = None if self._timeout is None else time.monotonic() + self._timeout
        device = self._collect()
        while len(self._rx) < size:
            now = time.monotonic()
            if deadline is not None and now >= deadline:
                break
            if device.disconnected:
                break
            wait = 0.05
            upcoming = device.next_event()
            if upcoming is not None:
                wait = min(wait, max(0.0, upcoming - now))
            if deadline is not None:
                wait = min(wait, deadline - now)
            time.sleep(wait)
            device = self._collect()
        data = bytes(self._rx[:size])
        del self._rx[:size]
        return data

    def write(self, data: bytes) -> int:
        device = self._live()
        if device.disconnected:
            raise SerialException(_DISCONNECTED)
        device.receive(bytes(data), time.monotonic())
        return len(data)

    def reset_input_buffer(self) -> None:
        self._collect()
        self._rx.clear()

    def reset_output_buffer(self) -> None:
        self._live()

    @property
    def out_waiting(self) -> int:
        self._live()
        return 0

    def _update_break_state(self) -> None:
        """No break condition on a simulated line."""

    def _update_rts_state(self) -> None:
        """No modem lines on a simulated line."""

    def _update_dtr_state(self) -> None:
        """No modem lines on a simulated line."""

    @property
    def cts(self) -> bool:
        self._live()
        return True

    @property
    def dsr(self) -> bool:
        self._live()
        return True

    @property
    def ri(self) -> bool:
        self._live()
        return False

    @property
    def cd(self) -> bool:
        self._live()
        return True
