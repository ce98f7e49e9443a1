"""Serial driver: turns a port's byte stream into :class:`Reading` objects.

The driver is protocol-agnostic: framing and parsing come from a
:class:`~rigkit.rangefinder.protocols.ProtocolSpec`. The port is any pyserial
URL (``/dev/ttyUSB0``, ``/dev/rfcomm0``, ``COM3``, ``socket://host:port``,
``sim://trupulse``) or an already-open object with ``read``/``write``/``close``
(pyserial semantics: ``read`` returns within its own timeout).

What real lines do, and what the driver does about it:

* noise, partial lines and unknown sentence types: skipped and counted;
* a bad checksum: skipped and counted, never returned as a reading;
* silence: :class:`ReadTimeout` after ``timeout`` seconds;
* a pulled cable (read/write fails): the port is closed and
  :class:`PortError` raised.

Every byte in either direction can be appended to a raw log for audit.
"""

from __future__ import annotations

import errno
import os
import time
from collections import deque
from dataclasses import dataclass, fields, replace
from datetime import UTC, datetime
from pathlib import Path
from types import TracebackType
from typing import Any, Protocol, TextIO

import serial

from rigkit.core.outputs import OutputLog
from rigkit.errors import InputError
from rigkit.rangefinder.defaults import DEFAULT_TIMEOUT_S
from rigkit.rangefinder.framing import (
    ChecksumError,
    FrameError,
    Notice,
    ProtocolSpec,
    RangefinderError,
    Reading,
    escape_bytes,
)
from rigkit.rangefinder.protocols import get_protocol

if "rigkit.rangefinder" not in serial.protocol_handler_packages:  # sim:// URLs as ports
    serial.protocol_handler_packages.append("rigkit.rangefinder")
POLL_S = 0.1
"""Read timeout set on ports the driver opens; bounds timeout overshoot."""
PARITIES = ("N", "E", "O", "M", "S")
BYTESIZES = (5, 6, 7, 8)
STOPBITS = (1, 1.5, 2)


class PortError(RangefinderError):
    """The port cannot be opened, or the connection was lost (port closed)."""


class ReadTimeout(RangefinderError):
    """No reading arrived within the timeout."""


class DeviceError(RangefinderError):
    """The device answered a request with a failure (rejected it, no target)."""


class SerialLike(Protocol):
    """What the driver needs from a port object (pyserial ``Serial`` fits)."""

    def read(self, size: int = 1) -> bytes: ...

    def write(self, data: bytes, /) -> int | None: ...

    def close(self) -> None: ...


@dataclass(frozen=True)
class LineStats:
    """Counts of what arrived on the line since the driver was opened.

    ``frames``: all chunks cut from the stream; ``readings``: returned ranges;
    ``bad_checksums``: frames rejected for their checksum; ``malformed``: noise,
    cut-off lines and unparseable frames; ``other``: well-formed frames
    without a range (other sentence types, acknowledgements, prompts);
    ``unknown``: well-formed frames of types the protocol does not define;
    ``bytes_received``: every byte read from the port.
    """

    frames: int = 0
    readings: int = 0
    bad_checksums: int = 0
    malformed: int = 0
    other: int = 0
    unknown: int = 0
    bytes_received: int = 0

    def since(self, earlier: LineStats) -> LineStats:
        """The counts accumulated after the snapshot ``earlier``."""
        return LineStats(
            **{f.name: getattr(self, f.name) - getattr(earlier, f.name) for f in fields(self)}
        )

    def describe(self) -> str:
        """E.g. ``"5 frames: 1 reading, 2 bad checksums, 2 malformed"``."""
        parts = [
            f"{count} {label}" if count == 1 else f"{count} {plural}"
            for count, label, plural in (
                (self.readings, "reading", "readings"),
                (self.bad_checksums, "bad checksum", "bad checksums"),
                (self.malformed, "malformed", "malformed"),
                (self.other, "other message", "other messages"),
                (self.unknown, "unknown sentence", "unknown sentences"),
            )
            if count
        ]
        noun = "frame" if self.frames == 1 else "frames"
        return f"{self.frames} {noun}" + (": " + ", ".join(parts) if parts else "")


def _now_iso() -> str:
    return datetime.now(UTC).isoformat(timespec="microseconds")


class Rangefinder:
    """A rangefinder on an open port; use :func:`open_rangefinder` to make one.

    The object owns the port (and the raw log): :meth:`close` closes both, and
    a lost connection closes the port. Use it as a context manager.
    """

    def __init__(
        self,
        port: SerialLike,
        protocol: ProtocolSpec,
        *,
        name: str,
        timeout: float = DEFAULT_TIMEOUT_S,
        raw_log: TextIO | None = None,
    ) -> None:
        self._port = port
        self._spec = protocol
        self._name = name
        self._timeout = timeout
        self._log = raw_log
        self._buffer = b""
        self._frames: deque[bytes] = deque()
        self._stats = LineStats()
        self._closed = False

    @property
    def name(self) -> str:
        """The port URL or name, as used in messages."""
        return self._name

    @property
    def protocol(self) -> ProtocolSpec:
        return self._spec

    @property
    def port(self) -> SerialLike:
        return self._port

    @property
    def stats(self) -> LineStats:
        """What has arrived on the line so far."""
        return self._stats

    @property
    def closed(self) -> bool:
        """True after :meth:`close` or a lost connection."""
        return self._closed

    def read(self, *, timeout: float | None = None, trigger: bool | None = None) -> Reading:
        """Wait for the next reading and return it.

        ``timeout``: seconds to wait (default: the one given at open; ``inf``
        waits forever). ``trigger``: send the protocol's measurement request
        first (default: only for devices that measure solely on request, such
        as the Vectronix; a TruPulse waits for the user's shot). Raises
        :class:`ReadTimeout`, :class:`PortError` (connection lost, port now
        closed) or :class:`DeviceError` (the device refused or found no target).
        """
        if self._closed:
            raise PortError(f"{self._name} is closed")
        limit = self._timeout if timeout is None else timeout
        requested = self._spec.request_by_default if trigger is None else trigger
        if requested:
            self._discard_input()
            self._send(self._spec.request)
        before = self._stats
        deadline = time.monotonic() + limit
        while True:
            while self._frames:
                reading = self._handle(self._frames.popleft(), requested)
                if reading is not None:
                    return reading
            remaining = deadline - time.monotonic()
            if remaining <= 0:
                raise ReadTimeout(self._timeout_message(limit, before, requested))
            chunk = self._receive(remaining)
            if chunk:
                frames, self._buffer = self._spec.split(self._buffer + chunk)
                self._frames.extend(frames)

    def close(self) -> None:
        """Close the port and the raw log (idempotent)."""
        if not self._closed:
            self._closed = True
            self._note("closed")
            try:
                self._port.close()
            except (serial.SerialException, OSError):
                pass
        if self._log is not None:
            self._log.close()
            self._log = None

    def __enter__(self) -> Rangefinder:
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.close()

    # -- internals ---------------------------------------------------------

    def _handle(self, frame: bytes, requested: bool) -> Reading | None:
        stats = replace(self._stats, frames=self._stats.frames + 1)
        try:
            result = self._spec.parse(frame, time.time())
        except ChecksumError:
            self._stats = replace(stats, bad_checksums=stats.bad_checksums + 1)
            return None
        except FrameError:
            self._stats = replace(stats, malformed=stats.malformed + 1)
            return None
        if isinstance(result, Reading):
            self._stats = replace(stats, readings=stats.readings + 1)
            return result
        self._stats = self._count_notice(stats, result)
        if result.error is not None and requested:
            raise DeviceError(f"{self._name}: {result.error}")
        return None

    @staticmethod
    def _count_notice(stats: LineStats, notice: Notice) -> LineStats:
        if notice.known:
            return replace(stats, other=stats.other + 1)
        return replace(stats, unknown=stats.unknown + 1)

    def _timeout_message(self, limit: float, before: LineStats, requested: bool) -> str:
        head = f"no reading from {self._name} within {limit:.1f} s"
        seen = self._stats.since(before)
        if seen.bytes_received == 0:
            what = "no answer to the request" if requested else "nothing received (was it fired?)"
            return f"{head}: {what}; check power, cable or pairing, and baud rate"
        if seen.frames == 0:
            return f"{head}: {seen.bytes_received} bytes but no complete frame (wrong baud rate?)"
        return f"{head} (received {seen.describe()})"

    def _receive(self, wait: float) -> bytes:
        started = time.monotonic()
        try:
            data = self._port.read(1)
            waiting = getattr(self._port, "in_waiting", 0) if data else 0
            if waiting:
                data += self._port.read(waiting)
        except (serial.SerialException, OSError) as exc:
            raise self._lost(exc) from None
        if data:
            self._trace("RX", data)
            self._stats = replace(
                self._stats, bytes_received=self._stats.bytes_received + len(data)
            )
        elif time.monotonic() - started < POLL_S / 2:
            # The port returned at once (a non-blocking object): don't spin.
            time.sleep(min(POLL_S, wait))
        return bytes(data)

    def _send(self, data: bytes) -> None:
        self._trace("TX", data)
        try:
            self._port.write(data)
            flush = getattr(self._port, "flush", None)
            if flush is not None:
                flush()
        except (serial.SerialException, OSError) as exc:
            raise self._lost(exc) from None

    def _discard_input(self) -> None:
        """Drop stale bytes (late answers to an earlier request) before a request."""
        self._buffer = b""
        self._frames.clear()
        reset = getattr(self._port, "reset_input_buffer", None)
        if reset is None:
            return
        try:
            reset()
        except (serial.SerialException, OSError) as exc:
            raise self._lost(exc) from None

    def _lost(self, exc: BaseException) -> PortError:
        reason = str(exc).strip() or type(exc).__name__
        self._note(f"lost connection: {reason}")
        self._closed = True
        try:
            self._port.close()
        except (serial.SerialException, OSError):
            pass
        return PortError(
            f"lost connection to {self._name}: {reason}; port closed "
            "(check the cable or the Bluetooth link)"
        )

    def _trace(self, direction: str, data: bytes) -> None:
        if self._log is not None:
            self._log.write(f"{_now_iso()} {direction} {escape_bytes(data)}\n")
            self._log.flush()

    def _note(self, text: str) -> None:
        if self._log is not None:
            self._log.write(f"{_now_iso()} -- {text}\n")
            self._log.flush()


def _open_error(url: str, exc: BaseException) -> PortError:
    code = getattr(exc, "errno", None)
    if code == errno.ENOENT:
        why = "no such device (is it plugged in or paired? try: ls /dev/ttyUSB* /dev/rfcomm*)"
    elif code == errno.EACCES:
        why = "permission denied (add your user to the 'dialout' group and log in again)"
    elif code in (errno.EBUSY, errno.EAGAIN):
        why = "the port is in use by another program"
    elif isinstance(code, int) and code > 0:
        why = os.strerror(code)
    else:
        why = str(exc).strip() or type(exc).__name__
    return PortError(f"cannot open {url}: {why}")


def open_serial(
    url: str, baud: int, *, bytesize: int = 8, parity: str = "N", stopbits: float = 1
) -> Any:
    """Open a pyserial URL or device path for an instrument (reads return within
    :data:`POLL_S`), its input emptied; :class:`PortError` saying why it cannot be
    opened (no such device, permission, in use)."""
    try:
        port = serial.serial_for_url(
            url,
            baudrate=baud,
            bytesize=bytesize,
            parity=parity,
            stopbits=stopbits,
            timeout=POLL_S,
            write_timeout=2.0,
            exclusive=True if "://" not in url else None,
        )
        port.reset_input_buffer()
    except (serial.SerialException, OSError, ValueError) as exc:
        raise _open_error(url, exc) from None
    return port


def port_name(port: object) -> str:
    """How messages name an open port object: its ``name`` or ``port``, else its type."""
    for attribute in ("name", "port"):
        value = getattr(port, attribute, None)
        if isinstance(value, str) and value:
            return value
    return type(port).__name__


def open_rangefinder(
    url: str | SerialLike,
    protocol: str = "trupulse",
    baud: int | None = None,
    timeout: float = DEFAULT_TIMEOUT_S,
    log_path: str | os.PathLike[str] | None = None,
    *,
    bytesize: int = 8,
    parity: str = "N",
    stopbits: float = 1,
) -> Rangefinder:
    """Open a rangefinder and return a :class:`Rangefinder` (a context manager).

    ``url``: a pyserial URL or device path, or an open port object (whose own
    settings are then left alone). ``protocol``: ``"trupulse"`` or
    ``"vectronix"``. ``baud`` (default: the protocol's), ``bytesize``,
    ``parity`` (N/E/O/M/S) and ``stopbits`` set the framing. ``timeout`` is
    the default wait for a reading in seconds. ``log_path``: append every byte
    sent and received to this text file. Raises :class:`PortError` when the
    port cannot be opened and ``InputError`` for bad settings.
    """
    spec = get_protocol(protocol)
    if not timeout > 0:
        raise InputError(f"timeout must be positive, got {timeout}")
    rate = spec.default_baud if baud is None else baud
    if rate <= 0:
        raise InputError(f"baud rate must be positive, got {rate}")
    if bytesize not in BYTESIZES:
        raise InputError(f"data bits must be one of 5, 6, 7, 8, got {bytesize}")
    if parity not in PARITIES:
        raise InputError(f"parity must be one of N, E, O, M, S, got {parity!r}")
    if stopbits not in STOPBITS:
        raise InputError(f"stop bits must be 1, 1.5 or 2, got {stopbits}")
    log: TextIO | None = None
    if log_path is not None:  # never a file rigkit did not start, a link or a FIFO
        log = OutputLog(Path(log_path), "--raw-log", "raw-log", encoding="ascii")
    port: Any
    if isinstance(url, str):
        name = url
        try:
            port = open_serial(url, rate, bytesize=bytesize, parity=parity, stopbits=stopbits)
        except PortError:
            if log is not None:
                log.close()
            raise
    else:
        port, name = url, port_name(url)
    framing = f"{bytesize}{parity}{stopbits:g}"
    rangefinder = Rangefinder(port, spec, name=name, timeout=timeout, raw_log=log)
    rangefinder._note(f"opened {name} protocol={spec.name} baud={rate} {framing}")
    return rangefinder


__all__ = [
    "DEFAULT_TIMEOUT_S",
    "DeviceError",
    "LineStats",
    "PortError",
    "ReadTimeout",
    "Rangefinder",
    "SerialLike",
    "open_rangefinder",
    "open_serial",
    "port_name",
]
