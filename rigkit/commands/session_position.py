"""``rigkit session set-position`` and ``set-rig``: where the tripod stood (typed in or
from a GPS), and the rig profile the session is processed with."""

from __future__ import annotations

import argparse
from pathlib import Path

from rigkit.commands import count, finite

EXAMPLE = """examples:
  rigkit session set-position capture/ridge-0412 --lat 46.55123 --lon 7.98456 --height-m 1012
  rigkit session set-position capture/ridge-0412 --lat 46.55123 --lon 7.98456 \
      --height-m 1012.4 --height-datum EPSG:5728           # a height in LN02 (Swiss heights)
  rigkit session set-position capture/ridge-0412 --gps /dev/ttyACM0 --fixes 10
  rigkit session set-position capture/ridge-0412 --gps 'sim://gps?lat=46.55&lon=7.98&noise=3'

Record it at the left position (the targets are marked in the left image). With
2 or more targets whose laser readings carry azimuth and inclination, `rigkit export`
then places the points on the map (docs/outputs.md). A GPS's height is above its own
mean sea level, and its geoid separation is kept with it; say what a typed height is
measured from with --height-datum, so that the exported files can say what Z is.
"""


def register_set_position(actions: argparse._SubParsersAction) -> None:
    p = actions.add_parser(
        "set-position", help="record where the tripod stood (typed in, or from a GPS)",
        epilog=EXAMPLE, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("session", type=Path)
    p.add_argument("--lat", type=finite, help="latitude, degrees (WGS 84, north positive)")
    p.add_argument("--lon", type=finite, help="longitude, degrees (east positive)")
    p.add_argument("--height-m", type=finite, help="height, metres (above mean sea level, "
                   "as a GPS shows it)")
    p.add_argument("--height-datum", metavar="ellipsoidal|EPSG:CODE",
                   help="what the typed height is measured from: ellipsoidal (WGS 84) or "
                   "a vertical CRS (e.g. EPSG:5728 LN02, EPSG:3855 EGM2008); default: not "
                   "stated, and the export says so")
    p.add_argument("--gps", metavar="URL", help="read NMEA GGA sentences from a GPS receiver "
                   "on a serial port or pyserial URL (sim://gps?... simulates one)")
    p.add_argument("--fixes", type=count, default=5, help="GPS fixes to average (default 5)")
    p.add_argument("--baud", type=int, default=4800, help="GPS baud rate (default 4800)")
    p.add_argument("--timeout", type=finite, default=30.0,
                   help="seconds to wait for each GPS fix (default 30)")
    p.set_defaults(runner="rigkit.commands.session_position_run:run_set_position")


SET_RIG_EXAMPLE = """example:
  rigkit rig calibrate capture/ridge-0412 --out rigs/ridge-0412.yaml
  rigkit session set-rig capture/ridge-0412 --rig rigs/ridge-0412.yaml
  rigkit process capture/ridge-0412

The session keeps a copy of the profile's values, as `session new` does; history.log
names the profile it replaced. Process the session again for results under it.
"""


def register_set_rig(actions: argparse._SubParsersAction) -> None:
    p = actions.add_parser(
        "set-rig", help="process the session with another rig profile (e.g. a calibrated one)",
        epilog=SET_RIG_EXAMPLE, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("session", type=Path)
    p.add_argument("--rig", type=Path, required=True, help="rig profile YAML (copied in)")
    p.set_defaults(runner="rigkit.commands.session_position_run:run_set_rig")
