"""Laser rangefinder ground truth: serial driver, protocols and simulator.

>>> from rigkit.rangefinder import open_rangefinder
>>> with open_rangefinder("sim://trupulse?interval=0.01", "trupulse", timeout=2) as rf:
...     round(rf.read().slope_distance_m)
302

Units: metres and degrees; inclination is positive above the horizontal.
See ``docs/rangefinder.md`` for devices, pairing and how a laser range is
compared with a depth map (:mod:`rigkit.rangefinder.ranging`).

Its public names are imported on first use (:mod:`rigkit.core.lazy`): the values
``rigkit rangefinder --help`` shows (:mod:`rigkit.rangefinder.defaults`) load neither
pyserial nor the drivers. The driver registers this package with pyserial, so that
``sim://`` URLs (:mod:`rigkit.rangefinder.protocol_sim`) open as ports.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from rigkit.core.lazy import exports

if TYPE_CHECKING:
    from rigkit.rangefinder.defaults import DEFAULT_TIMEOUT_S
    from rigkit.rangefinder.driver import (
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

__getattr__ = exports(__name__, {
    "ChecksumError": "framing",
    "DEFAULT_TIMEOUT_S": "defaults",
    "DeviceError": "driver",
    "FrameError": "framing",
    "LineStats": "driver",
    "Notice": "framing",
    "PROTOCOLS": "protocols",
    "PortError": "driver",
    "ProtocolSpec": "framing",
    "Rangefinder": "driver",
    "RangefinderError": "framing",
    "ReadTimeout": "driver",
    "Reading": "framing",
    "SerialLike": "driver",
    "additive_checksum": "vectronix",
    "depth_from_range": "ranging",
    "encode_trupulse_hv": "trupulse",
    "get_protocol": "protocols",
    "nmea_checksum": "trupulse",
    "open_rangefinder": "driver",
    "parse_trupulse": "trupulse",
    "parse_vectronix": "vectronix",
    "range_from_depth": "ranging",
    "split_trupulse": "trupulse",
    "split_vectronix": "vectronix",
    "trupulse_sentence": "trupulse",
    "vectronix_frame": "vectronix",
})
