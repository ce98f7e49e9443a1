"""What the rangefinder code and ``rigkit rangefinder --help`` share: each protocol's
default baud rate, the wait for a reading, and what the simulator's URL options do. One
place for both, in a module that imports nothing, so that building the command line's
parser loads neither pyserial nor the drivers."""

from __future__ import annotations

DEFAULT_BAUDS = {"trupulse": 4800, "vectronix": 115200}
"""Each protocol's default baud rate (:data:`rigkit.rangefinder.protocols.PROTOCOLS`)."""
DEFAULT_TIMEOUT_S = 30.0
"""Default wait for one reading, in seconds (time to aim and fire by hand)."""
SIM_OPTIONS: dict[str, str] = {
    "distance": "true slope distance to the target in metres (default 302)",
    "lat": "gps: latitude in degrees, north positive (default 46.5)",
    "lon": "gps: longitude in degrees, east positive (default 7.5)",
    "height": "gps: height above mean sea level in metres (default 500)",
    "geoid": "gps: the geoid's height above the WGS 84 ellipsoid in metres, GGA's geoid "
    "separation (default 47.3)",
    "inclination": "trupulse: inclination in degrees, positive up (default 1.2)",
    "azimuth": "trupulse: azimuth in degrees (default 47.3)",
    "unit": "trupulse: unit the device sends, M, F or Y (default M)",
    "interval": "trupulse: seconds between the simulated user's shots, 0 = only on $GO; "
    "gps: seconds between fixes (default 1)",
    "noise": "1-sigma range noise in metres; gps: 1-sigma horizontal position noise, m "
    "(default 0)",
    "low_quality": "trupulse: probability a shot is flagged low-quality (default 0)",
    "miss": "probability a shot finds no target (default 0)",
    "other": "trupulse, gps: probability of another sentence before a shot or fix "
    "(default 0)",
    "nofix": "gps: GGA sentences without a fix before the first fix (default 0)",
    "garbage": "probability of line noise and a cut-off sentence before a frame (default 0)",
    "bad_checksum": "probability a frame is sent with a wrong checksum (default 0)",
    "silent": "1 = the device never sends anything (default 0)",
    "disconnect_after": "pull the cable halfway through frame N+1 (default: never)",
    "seed": "random seed (default 0)",
}
"""Simulator URL options (``sim://<device>?key=value&...``) and what they do."""
