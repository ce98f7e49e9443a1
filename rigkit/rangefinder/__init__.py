"""Laser rangefinder ground truth: serial driver, protocols and simulator.

>>> from rigkit.rangefinder import open_rangefinder
>>> with open_rangefinder("sim://trupulse?interval=0.01", "trupulse", timeout=2) as rf:
...     round(rf.read().slope_distance_m)
302

Units: metres and degrees; inclination is positive above the horizontal.
See ``docs/rangefinder.md`` for devices, pairing and how a laser range is
compared with a depth map (:mod:`rigkit.rangefinder.ranging`).

Importing this package registers it with pyserial so that ``sim://`` URLs
(:mod:`rigkit.rangefinder.protocol_sim`) work in ``serial.serial_for_url``.
"""

from __future__ import annotations

import serial

from rigkit.rangefinder.driver import (
    DEFAULT_TIMEOUT_S,
    DeviceError,
    LineStats,
    PortError,
    Rangefinder,
    ReadTimeout,
    SerialLike,
    open_rangefinder,
)
from rigkit.rangefinder.framing import (
    ChecksumError,
    FrameError,
    Notice,
    ProtocolSpec,
    RangefinderError,
    Reading,
)
from rigkit.rangefinder.protocols import PROTOCOLS, get_protocol
from rigkit.rangefinder.ranging import depth_from_range, range_from_depth
from rigkit.rangefinder.trupulse import (
    encode_trupulse_hv,
    nmea_checksum,
    parse_trupulse,
    split_trupulse,
    trupulse_sentence,
)
from rigkit.rangefinder.vectronix import (
    additive_checksum,
    parse_vectronix,
    split_vectronix,
    vectronix_frame,
)

if __name__ not in serial.protocol_handler_packages:
    serial.protocol_handler_packages.append(__name__)


__all__ = [
    "DEFAULT_TIMEOUT_S",
    "PROTOCOLS",
    "ChecksumError",
    "DeviceError",
    "FrameError",
    "LineStats",
    "Notice",
    "PortError",
    "ProtocolSpec",
    "RangefinderError",
    "Rangefinder",
    "ReadTimeout",
    "Reading",
    "SerialLike",
    "additive_checksum",
    "depth_from_range",
    "encode_trupulse_hv",
    "get_protocol",
    "nmea_checksum",
    "open_rangefinder",
    "parse_trupulse",
    "parse_vectronix",
    "range_from_depth",
    "split_trupulse",
    "split_vectronix",
    "trupulse_sentence",
    "vectronix_frame",
]
