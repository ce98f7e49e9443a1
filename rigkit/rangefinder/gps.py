"""A GPS receiver on a serial line: the tripod's position from NMEA 0183 GGA sentences.

Same shape as the rangefinder (:mod:`rigkit.rangefinder.driver`): pure functions map
bytes to values (:func:`parse_nmea`, :func:`encode_gga`; testable with scripted bytes),
and :class:`GpsReceiver` reads a port object with ``read``/``close`` (any pyserial URL,
``sim://gps?...`` for the simulator in :mod:`rigkit.rangefinder.sim`).

A GGA sentence (NMEA 0183; talker GP, GN, GL, GA, GB or BD)::

    $GPGGA,hhmmss.ss,ddmm.mmmm,N,dddmm.mmmm,E,q,ss,h.h,a.a,M,g.g,M,,*CS

q is the fix quality (0 = no fix), ss the satellites in use, h.h the horizontal
dilution of precision, a.a the antenna's height above mean sea level in metres (the
receiver's own geoid model, which GGA does not name), g.g the geoid's height above the
WGS 84 ellipsoid there (the "geoid separation" N: the ellipsoidal height is a.a + g.g;
empty where the receiver does not send it). The checksum is the XOR of the bytes
between ``$`` and ``*``, as the TruPulse's. Other sentences (RMC, GSV, ...) are noted
and skipped.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass
from types import TracebackType

import serial

from rigkit.errors import InputError
from rigkit.rangefinder.driver import POLL_S, PortError, ReadTimeout, SerialLike, open_serial
from rigkit.rangefinder.framing import (
    FrameError,
    Notice,
    ascii_text,
    short,
    split_checksum,
    split_frames,
)
from rigkit.rangefinder.trupulse import nmea_checksum, trupulse_sentence

GPS_BAUD = 4800
"""NMEA 0183's standard rate; many receivers use 9600 (``--baud``)."""
_GGA_FIELDS = 9
"""GGA data fields rigkit needs: time to the altitude's unit."""


@dataclass(frozen=True)
class GpsFix:
    """One GGA position. ``lat_deg``/``lon_deg``: WGS 84 degrees, north and east
    positive; ``height_m``: antenna above mean sea level, m; ``quality``: GGA fix
    quality (1 GPS, 2 DGPS, 4 RTK fixed, 5 RTK float, ...); ``satellites`` in use;
    ``hdop``: horizontal dilution of precision, None if not sent; ``raw``: the sentence
    as received, without its line end; ``geoid_separation_m``: the geoid's height above
    the WGS 84 ellipsoid, m (``height_m`` plus it is the ellipsoidal height), None if not
    sent."""

    lat_deg: float
    lon_deg: float
    height_m: float
    quality: int
    satellites: int
    hdop: float | None
    raw: bytes
    geoid_separation_m: float | None = None


def split_nmea(buffer: bytes) -> tuple[list[bytes], bytes]:
    """Cut NMEA sentences (``$`` ... CR and/or LF) off the front of ``buffer``."""
    return split_frames(buffer, start=b"$", terminators=b"\r\n")


def parse_nmea(frame: bytes) -> GpsFix | Notice:
    """One NMEA sentence: a GGA with a fix is a :class:`GpsFix`; a GGA without a fix a
    :class:`Notice` whose ``error`` says so; any other sentence a Notice. Raises
    :class:`~rigkit.rangefinder.framing.ChecksumError` on a checksum mismatch and
    :class:`~rigkit.rangefinder.framing.FrameError` on anything malformed."""
    text = ascii_text(frame)
    fields = split_checksum(text, "$", nmea_checksum).split(",")
    kind = fields[0][2:] if len(fields[0]) == 5 else fields[0]
    if kind != "GGA":
        return Notice(kind=fields[0], fields=tuple(fields[1:]), raw=frame)
    values = fields[1:]
    if len(values) < _GGA_FIELDS:
        raise FrameError(f"GGA sentence has {len(values)} fields, expected at least "
                         f"{_GGA_FIELDS}: {short(text)!r}")
    quality = _whole(values[5], "fix quality")
    satellites = _whole(values[6], "satellites") if values[6] else 0
    if quality == 0:
        return Notice(kind="GGA", fields=tuple(values), raw=frame,
                      error=f"no fix yet ({satellites} satellites)")
    if values[9] not in ("M", ""):
        raise FrameError(f"GGA altitude unit {values[9]!r}, expected M")
    separation, unit = (values[10], values[11]) if len(values) > 11 else ("", "")
    if separation and unit not in ("M", ""):
        raise FrameError(f"GGA geoid separation unit {unit!r}, expected M")
    return GpsFix(
        lat_deg=_coordinate(values[1], values[2], "NS", 2),
        lon_deg=_coordinate(values[3], values[4], "EW", 3),
        height_m=_number(values[8], "altitude"),
        quality=quality,
        satellites=satellites,
        hdop=_number(values[7], "HDOP") if values[7] else None,
        raw=frame.rstrip(b"\r\n"),
        geoid_separation_m=_number(separation, "geoid separation") if separation else None,
    )


def _number(text: str, what: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise FrameError(f"GGA {what} {text!r} is not a number") from None
    if not math.isfinite(value):
        raise FrameError(f"GGA {what} {text!r} is not a number")
    return value


def _whole(text: str, what: str) -> int:
    if not text.isdigit():
        raise FrameError(f"GGA {what} {text!r} is not a whole number")
    return int(text)


def _coordinate(text: str, hemisphere: str, letters: str, degree_digits: int) -> float:
    """Degrees from NMEA's (d)ddmm.mmmm and a hemisphere letter (N/S or E/W)."""
    if hemisphere not in letters or len(hemisphere) != 1:
        raise FrameError(f"GGA hemisphere {hemisphere!r}, expected {' or '.join(letters)}")
    head = text.split(".")[0]
    if len(head) != degree_digits + 2 or not head.isdigit():
        raise FrameError(f"GGA coordinate {text!r} is not {'d' * degree_digits}mm.mmmm")
    degrees, minutes = int(head[:degree_digits]), _number(text[degree_digits:], "minutes")
    value = degrees + minutes / 60.0
    if minutes >= 60.0 or value > 90 * (degree_digits - 1):
        raise FrameError(f"GGA coordinate {text!r} out of range")
    return -value if hemisphere == letters[1] else value


def encode_gga(
    lat_deg: float,
    lon_deg: float,
    height_m: float,
    *,
    utc_s: float = 0.0,
    quality: int = 1,
    satellites: int = 9,
    hdop: float = 0.9,
    geoid_separation_m: float | None = 47.3,
) -> bytes:
    """The GGA sentence a receiver sends for a position (``utc_s``: seconds into the UTC
    day; ``height_m`` above mean sea level, ``geoid_separation_m`` the geoid above the
    ellipsoid, None: not sent), with CR LF; the inverse of :func:`parse_nmea` to 1e-6
    minutes (2 mm)."""
    def dm(value: float, digits: int) -> str:
        degrees, minutes = divmod(round(abs(value) * 60.0, 6), 60.0)
        return f"{int(degrees):0{digits}d}{minutes:09.6f}"

    separation = "" if geoid_separation_m is None else f"{geoid_separation_m:.2f}"
    hours, rest = divmod(utc_s % 86400.0, 3600.0)
    clock = f"{int(hours):02d}{int(rest // 60):02d}{rest % 60:05.2f}"
    position = ["", "", "", ""] if quality == 0 else [
        dm(lat_deg, 2), "N" if lat_deg >= 0 else "S", dm(lon_deg, 3), "E" if lon_deg >= 0 else "W"]
    return trupulse_sentence(["GPGGA", clock, *position, str(quality), f"{satellites:02d}",
                              f"{hdop:.1f}", f"{height_m:.2f}", "M", separation,
                              "M" if separation else "", "", ""])


class GpsReceiver:
    """A GPS receiver on an open port (a context manager; :func:`open_gps` makes one)."""

    def __init__(self, port: SerialLike, *, name: str, timeout: float) -> None:
        self._port = port
        self.name = name
        self._timeout = timeout
        self._buffer = b""
        self._frames: list[bytes] = []
        self._seen: list[str] = []  # what the current read got instead of a fix

    def read(self, timeout: float | None = None) -> GpsFix:
        """The next GGA fix; :class:`ReadTimeout` saying what arrived instead (nothing,
        no GGA, GGA without a fix) after ``timeout`` seconds (default: the one given at
        open), :class:`PortError` when the connection is lost."""
        limit = self._timeout if timeout is None else timeout
        deadline = time.monotonic() + limit
        self._seen = []
        while True:
            while self._frames:
                fix = self._handle(self._frames.pop(0))
                if fix is not None:
                    return fix
            if time.monotonic() >= deadline:
                raise ReadTimeout(f"no GPS fix from {self.name} within {limit:.1f} s: "
                                  f"{self._what_arrived()}")
            frames, self._buffer = split_nmea(self._buffer + self._receive())
            self._frames.extend(frames)

    def _handle(self, frame: bytes) -> GpsFix | None:
        try:
            result = parse_nmea(frame)
        except FrameError:
            self._seen.append("malformed")
            return None
        if isinstance(result, GpsFix):
            return result
        self._seen.append(result.error or "other")
        return None

    def _what_arrived(self) -> str:
        if not self._seen:
            return "nothing received; check power, cable and baud rate"
        no_fix = [s for s in self._seen if s.startswith("no fix")]
        if no_fix:
            return f"{len(no_fix)} GGA sentences, {no_fix[-1]}: wait under open sky"
        return (f"{len(self._seen)} sentences, none a GGA (turn GGA output on, or check "
                "the baud rate)")

    def _receive(self) -> bytes:
        try:
            data = self._port.read(256)
        except (serial.SerialException, OSError) as exc:
            self.close()
            raise PortError(f"lost connection to {self.name}: {exc}; port closed") from None
        if not data:
            time.sleep(POLL_S / 10)  # a port object that returns at once: don't spin
        return bytes(data)

    def close(self) -> None:
        try:
            self._port.close()
        except (serial.SerialException, OSError):
            pass

    def __enter__(self) -> GpsReceiver:
        return self

    def __exit__(self, kind: type[BaseException] | None, error: BaseException | None,
                 trace: TracebackType | None) -> None:
        self.close()


def open_gps(url: str, baud: int = GPS_BAUD, timeout: float = 30.0) -> GpsReceiver:
    """Open a GPS receiver on a pyserial URL or device path; :class:`PortError` if the
    port cannot be opened, InputError for bad settings."""
    if baud <= 0 or not timeout > 0:
        raise InputError(f"GPS baud rate {baud} and timeout {timeout} must be positive")
    return GpsReceiver(open_serial(url, baud), name=url, timeout=timeout)


@dataclass(frozen=True)
class MeanFix:
    """Fixes averaged: ``lat_deg``, ``lon_deg`` (WGS 84 degrees), ``height_m`` (above
    the receiver's mean sea level, m) and ``geoid_separation_m`` (m; None unless every
    fix sent one) over ``count`` fixes."""

    lat_deg: float
    lon_deg: float
    height_m: float
    geoid_separation_m: float | None
    count: int


def mean_position(fixes: list[GpsFix]) -> MeanFix:
    """The fixes averaged (a few metres apart: degrees average linearly); InputError
    for none."""
    if not fixes:
        raise InputError("no GPS fixes to average")
    n = len(fixes)
    separations = [f.geoid_separation_m for f in fixes if f.geoid_separation_m is not None]
    return MeanFix(sum(f.lat_deg for f in fixes) / n, sum(f.lon_deg for f in fixes) / n,
                   sum(f.height_m for f in fixes) / n,
                   sum(separations) / n if len(separations) == n else None, n)
