"""Simulated rangefinders, for tests and for trying rigkit without hardware.

The core (:class:`SimulatedTruPulse`, :class:`SimulatedVectronix`, and
:class:`SimulatedGps` for the tripod's position) is a pure
state machine driven by an explicit clock: feed it the host's bytes with
:meth:`~SimulatedDevice.receive`, collect what it has sent by a given time
with :meth:`~SimulatedDevice.output`. Two front ends run it on a real line:

* the pyserial URL handler :mod:`rigkit.rangefinder.protocol_sim`
  (``sim://trupulse?distance=234&noise=0.05``), for unit tests;
* :class:`PtySimulator`, which serves it on a pseudo-terminal
  (``/dev/pts/N``) for integration tests and ``rigkit rangefinder simulate``.

Faults are options: line noise and cut-off sentences, bad checksums, missed
shots, other sentence types, silence and a cable pull. All randomness comes
from ``random.Random(seed)``, so a configuration replays exactly.
"""

from __future__ import annotations

import math
import os
import random
import select
import threading
import time
import tty
from dataclasses import dataclass, fields
from types import TracebackType
from urllib.parse import parse_qsl, urlsplit

from rigkit.errors import InputError
from rigkit.rangefinder.defaults import SIM_OPTIONS
from rigkit.rangefinder.gps import encode_gga
from rigkit.rangefinder.trupulse import TRUPULSE_UNITS, encode_trupulse_hv, trupulse_sentence
from rigkit.rangefinder.vectronix import (
    VECTRONIX_TARGETS,
    additive_checksum,
    vectronix_frame,
    vectronix_range_field,
)

GEOID_LIMIT_M = 150.0
"""The geoid lies within about 110 m of the WGS 84 ellipsoid everywhere."""
_COMMON = ("noise", "garbage", "bad_checksum", "silent", "disconnect_after", "seed")
_APPLIES = {
    "trupulse": (*_COMMON, "distance", "miss", "inclination", "azimuth", "unit", "interval",
                 "low_quality", "other"),
    "vectronix": (*_COMMON, "distance", "miss"),
    "gps": (*_COMMON, "lat", "lon", "height", "geoid", "interval", "other", "nofix"),
}
"""The options each simulated device takes; the others must keep their defaults."""
# Bytes that delimit frames in either protocol; simulated noise avoids them so
# that noise corrupts the line without forging prompts or frame starts.
_FRAMING = frozenset(b"$><!\r\n*")


@dataclass(frozen=True)
class SimConfig:
    """A simulated device; see :data:`SIM_OPTIONS` for the meaning of each field.

    Distances in metres, angles in degrees (inclination positive up), times in
    seconds, probabilities in [0, 1].
    """

    device: str = "trupulse"
    distance: float = 302.0
    lat: float = 46.5
    lon: float = 7.5
    height: float = 500.0
    geoid: float = 47.3
    nofix: int = 0
    inclination: float = 1.2
    azimuth: float = 47.3
    unit: str = "M"
    interval: float = 1.0
    noise: float = 0.0
    low_quality: float = 0.0
    miss: float = 0.0
    other: float = 0.0
    garbage: float = 0.0
    bad_checksum: float = 0.0
    silent: bool = False
    disconnect_after: int | None = None
    seed: int = 0

    def __post_init__(self) -> None:
        if self.device not in _APPLIES:
            raise InputError(
                f"unknown simulated device {self.device!r} (choose trupulse, vectronix or gps)"
            )
        if not (math.isfinite(self.distance) and self.distance > 0):
            raise InputError(f"simulator distance must be positive, got {self.distance}")
        if self.unit not in TRUPULSE_UNITS:
            raise InputError(f"simulator unit must be M, F or Y, got {self.unit!r}")
        for name in ("interval", "noise"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value >= 0):
                raise InputError(f"simulator {name} must be >= 0, got {value}")
        for name in ("low_quality", "miss", "other", "garbage", "bad_checksum"):
            value = getattr(self, name)
            if not 0.0 <= value <= 1.0:
                raise InputError(f"simulator {name} is a probability in [0, 1], got {value}")
        if self.disconnect_after is not None and self.disconnect_after < 0:
            raise InputError(
                f"simulator disconnect_after must be >= 0, got {self.disconnect_after}"
            )
        if not (math.isfinite(self.geoid) and abs(self.geoid) <= GEOID_LIMIT_M):
            raise InputError(f"simulator geoid must be within +-{GEOID_LIMIT_M:g} m (the "
                             f"geoid's height above the ellipsoid), got {self.geoid}")
        if not (-90 <= self.lat <= 90 and -180 <= self.lon <= 180 and self.nofix >= 0):
            raise InputError(f"simulator lat {self.lat}, lon {self.lon} or nofix "
                             f"{self.nofix} out of range")
        for f in fields(self):
            if f.name not in ("device", *_APPLIES[self.device]) and (
                    getattr(self, f.name) != f.default):
                raise InputError(f"simulator option {f.name} does not apply to {self.device}")


def parse_sim_url(url: str) -> SimConfig:
    """The :class:`SimConfig` for ``sim://<device>?key=value&...``; InputError if invalid."""
    parts = urlsplit(url)
    if parts.scheme != "sim" or not parts.netloc:
        raise InputError(f"not a simulator URL: {url!r} (expected sim://trupulse?key=value&...)")
    values: dict[str, object] = {"device": parts.netloc.lower()}
    types = {f.name: f.type for f in fields(SimConfig)}
    for key, text in parse_qsl(parts.query, keep_blank_values=True):
        if key not in SIM_OPTIONS:
            raise InputError(
                f"unknown simulator option {key!r} (options: {', '.join(SIM_OPTIONS)})"
            )
        kind = str(types[key])
        try:
            if kind == "bool":
                if text not in ("0", "1", "true", "false"):
                    raise ValueError
                values[key] = text in ("1", "true")
            elif kind.startswith("int"):
                values[key] = int(text)
            elif kind == "float":
                values[key] = float(text)
            else:
                values[key] = text.upper()
        except ValueError:
            raise InputError(f"bad value for simulator option {key}: {text!r}") from None
    return SimConfig(**values)  # type: ignore[arg-type]


def _corrupt_checksum(frame: bytes, rng: random.Random) -> bytes:
    """The frame with its two checksum digits replaced by different ones."""
    star = frame.rindex(b"*")
    good = int(frame[star + 1 : star + 3], 16)
    bad = (good + rng.randrange(1, 256)) % 256
    return frame[: star + 1] + f"{bad:02X}".encode("ascii") + frame[star + 3 :]


class SimulatedDevice:
    """Shared behaviour: output queue, faults, command input.

    ``now`` arguments are seconds on any monotonic clock; the device never
    reads a clock itself.
    """

    def __init__(self, config: SimConfig, now: float) -> None:
        self.config = config
        self.rng = random.Random(config.seed)
        self.disconnected = False
        self.frames_sent = 0
        self._out = bytearray()
        self._inbox = b""

    def receive(self, data: bytes, now: float) -> None:
        """Bytes from the host; complete commands (ending CR or LF) are acted on."""
        if self.disconnected:
            return
        self._inbox += data
        while True:
            ends = [i for i in (self._inbox.find(b"\r"), self._inbox.find(b"\n")) if i != -1]
            if not ends:
                break
            end = min(ends)
            command, self._inbox = self._inbox[:end], self._inbox[end + 1 :]
            if command:
                self.command(command, now)

    def output(self, now: float) -> bytes:
        """Everything the device has sent by time ``now`` and not yet collected."""
        self.advance(now)
        data = bytes(self._out)
        self._out.clear()
        return data

    def next_event(self) -> float | None:
        """When the device will next send something unprompted, if ever."""
        return None

    def advance(self, now: float) -> None:
        """Run scheduled behaviour up to ``now``."""

    def command(self, command: bytes, now: float) -> None:
        """Act on one command line from the host."""

    def send(self, frame: bytes) -> None:
        """Put one frame on the line, applying the configured faults."""
        cfg = self.config
        if cfg.silent or self.disconnected:
            return
        if cfg.disconnect_after is not None and self.frames_sent >= cfg.disconnect_after:
            self._out += frame[: len(frame) // 2]
            self.disconnected = True
            return
        if self.rng.random() < cfg.garbage:
            self._out += self.noise(frame)
        if self.rng.random() < cfg.bad_checksum:
            frame = _corrupt_checksum(frame, self.rng)
        self._out += frame
        self.frames_sent += 1

    def send_prompt(self, prompt: bytes) -> None:
        """A one-byte prompt: not a frame, so only silence and disconnects apply."""
        if not (self.config.silent or self.disconnected):
            self._out += prompt

    def noise(self, frame: bytes) -> bytes:
        """Random non-framing bytes, then (half the time) a cut-off copy of ``frame``."""
        count = self.rng.randint(3, 24)
        junk = bytes(b for b in self.rng.randbytes(count) if b not in _FRAMING)
        if self.rng.random() < 0.5:
            junk += frame[: self.rng.randint(1, len(frame) - 3)]
        return junk


class SimulatedTruPulse(SimulatedDevice):
    """A TruPulse 360: pushes an HV sentence per shot.

    Shots come every ``interval`` seconds (the simulated user pulling the
    trigger) and on each ``$GO`` command; ``$PLTIT,RQ,ID`` and ``$ID`` get an
    ID sentence. Other commands are ignored, as the real device does.
    """

    def __init__(self, config: SimConfig, now: float) -> None:
        super().__init__(config, now)
        self._next_shot = now + config.interval if config.interval > 0 else None

    def next_event(self) -> float | None:
        return None if self.disconnected else self._next_shot

    def advance(self, now: float) -> None:
        while self._next_shot is not None and self._next_shot <= now and not self.disconnected:
            self.shot()
            self._next_shot += self.config.interval

    def command(self, command: bytes, now: float) -> None:
        self.advance(now)
        text = command.strip().upper()
        if text == b"$GO":
            self.shot()
        elif text in (b"$PLTIT,RQ,ID", b"$ID"):
            self.send(trupulse_sentence(["PLTIT", "ID", "TP360", "SIM"]))

    def shot(self) -> None:
        """One press of the fire button."""
        cfg, rng = self.config, self.rng
        if rng.random() < cfg.other:
            if rng.random() < 0.5:
                self.send(trupulse_sentence(["PLTIT", "HT", "12.30", cfg.unit]))
            else:
                self.send(trupulse_sentence(["PLTIT", "ZZ", "1", "2"]))
        if rng.random() < cfg.miss:
            return
        distance = max(0.1, cfg.distance + rng.gauss(0.0, cfg.noise))
        self.send(
            encode_trupulse_hv(
                distance,
                inclination_deg=cfg.inclination,
                azimuth_deg=cfg.azimuth,
                unit=cfg.unit,
                low_quality=rng.random() < cfg.low_quality,
            )
        )


class SimulatedVectronix(SimulatedDevice):
    """A Vectronix LRF module: answers ``>LM,Md,<3|5>*CS`` requests only.

    Sends the ready prompt ``<`` at power-up. A valid request gets ``>AC``,
    the range response (the target first, the remaining targets invalid, as
    in the manual's example) and ``<``. A bad checksum gets ``>NA,0``, an
    unsupported command ``>NA,1``, a bad target count ``>NA,2``, each
    followed by ``!``. Lines not starting with ``>`` are ignored.
    """

    def __init__(self, config: SimConfig, now: float) -> None:
        super().__init__(config, now)
        self.send_prompt(b"<")

    def command(self, command: bytes, now: float) -> None:
        text = command.strip()
        if not text.startswith(b">") or b"*" not in text:
            return
        body, _, checksum = text[1:].rpartition(b"*")
        if checksum.upper() != f"{additive_checksum(body):02X}".encode("ascii"):
            self._nack("0")
            return
        parts = body.decode("ascii", "replace").split(",")
        if parts[:2] != ["LM", "Md"]:
            self._nack("1")
            return
        if len(parts) != 3 or not parts[2].isdigit() or int(parts[2]) not in VECTRONIX_TARGETS:
            self._nack("2")
            return
        self.send(vectronix_frame("AC"))
        cfg, rng = self.config, self.rng
        hit = rng.random() >= cfg.miss
        distance = max(0.01, cfg.distance + rng.gauss(0.0, cfg.noise)) if hit else None
        ranges = [vectronix_range_field(distance)]
        ranges += [vectronix_range_field(None)] * (int(parts[2]) - 1)
        self.send(vectronix_frame(",".join(["LM", "Md", *ranges])))
        self.send_prompt(b"<")

    def _nack(self, code: str) -> None:
        self.send(vectronix_frame(f"NA,{code}"))
        self.send_prompt(b"!")


class SimulatedGps(SimulatedDevice):
    """A GPS receiver: a GGA sentence every ``interval`` seconds, the first ``nofix``
    without a fix, then at ``lat``/``lon``/``height`` (geoid separation ``geoid``) with
    Gaussian horizontal noise of ``noise`` metres per axis."""

    def __init__(self, config: SimConfig, now: float) -> None:
        super().__init__(config, now)
        self._next_fix = now + config.interval

    def next_event(self) -> float | None:
        return None if self.disconnected else self._next_fix

    def advance(self, now: float) -> None:
        while self._next_fix <= now and not self.disconnected:
            self.fix(self._next_fix)
            self._next_fix += max(self.config.interval, 1e-3)

    def fix(self, now: float) -> None:
        """One GGA sentence (and, with probability ``other``, an RMC before it)."""
        cfg, rng = self.config, self.rng
        if rng.random() < cfg.other:
            self.send(trupulse_sentence(["GPRMC", "", "V", "", "", "", "", "", "", "", ""]))
        metres_per_deg = 111_320.0
        north, east = rng.gauss(0.0, cfg.noise), rng.gauss(0.0, cfg.noise)
        lat = cfg.lat + north / metres_per_deg
        lon = cfg.lon + east / (metres_per_deg * max(math.cos(math.radians(cfg.lat)), 1e-6))
        quality = 0 if self.frames_sent < cfg.nofix else 1
        self.send(encode_gga(lat, lon, cfg.height, utc_s=now, quality=quality,
                             satellites=9 if quality else 3, geoid_separation_m=cfg.geoid))


def make_device(config: SimConfig, now: float) -> SimulatedDevice:
    """The simulated device ``config`` describes, powered on at time ``now``."""
    devices = {"vectronix": SimulatedVectronix, "gps": SimulatedGps}
    return devices.get(config.device, SimulatedTruPulse)(config, now)


class PtySimulator:
    """Serve a simulated device on a pseudo-terminal from a background thread.

    ``start()`` returns the device path (``/dev/pts/N``) to open with any
    serial program. The line is raw (no echo, no CR/LF translation). Output
    nobody reads is dropped, like a real UART's. A ``disconnect_after`` fault
    closes the pty, which the reader sees exactly as a pulled USB cable.
    Use as a context manager; :meth:`stop` is idempotent.
    """

    def __init__(self, config: SimConfig) -> None:
        self.config = config
        self.path = ""
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._master = -1
        self._slave = -1

    def start(self) -> str:
        """Open the pty, start serving, return the device path."""
        self._master, self._slave = os.openpty()
        tty.setraw(self._slave)
        os.set_blocking(self._master, False)
        self.path = os.ttyname(self._slave)
        self._thread = threading.Thread(target=self._serve, name="rangefinder-sim", daemon=True)
        self._thread.start()
        return self.path

    @property
    def running(self) -> bool:
        """True until stopped or until a simulated disconnect closed the line."""
        return self._thread is not None and self._thread.is_alive()

    def wait(self, timeout: float) -> None:
        """Block up to ``timeout`` seconds or until the simulator stops."""
        if self._thread is not None:
            self._thread.join(timeout)

    def stop(self) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join()

    def __enter__(self) -> PtySimulator:
        self.start()
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.stop()

    def _serve(self) -> None:
        device = make_device(self.config, time.monotonic())
        pending = b""
        try:
            while not self._stop.is_set():
                pending = (pending + device.output(time.monotonic()))[-4096:]
                if pending:
                    try:
                        pending = pending[os.write(self._master, pending) :]
                    except BlockingIOError:
                        pass
                if device.disconnected:
                    return
                wait = 0.05
                upcoming = device.next_event()
                if upcoming is not None:
                    wait = min(wait, max(0.0, upcoming - time.monotonic()))
                ready, _, _ = select.select([self._master], [], [], wait)
                if ready:
                    try:
                        data = os.read(self._master, 1024)
                    except (BlockingIOError, InterruptedError):
                        continue
                    device.receive(data, time.monotonic())
        finally:
            os.close(self._master)
            os.close(self._slave)
