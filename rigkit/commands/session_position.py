"""``rigkit session set-position`` and ``set-rig``: where the tripod stood (typed in or
from a GPS), and the rig profile the session is processed with."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

from rigkit.commands import count

EXAMPLE = """examples:
  rigkit session set-position capture/ridge-0412 --lat 46.55123 --lon 7.98456 --height-m 1012
  rigkit session set-position capture/ridge-0412 --gps /dev/ttyACM0 --fixes 10
  rigkit session set-position capture/ridge-0412 --gps 'sim://gps?lat=46.55&lon=7.98&noise=3'

Record it at the left position (the targets are marked in the left image). With
2 or more targets whose laser readings carry azimuth and inclination, `rigkit export`
then places the points on the map (docs/outputs.md).
"""


def register_set_position(actions: argparse._SubParsersAction) -> None:
    p = actions.add_parser(
        "set-position", help="record where the tripod stood (typed in, or from a GPS)",
        epilog=EXAMPLE, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("session", type=Path)
    p.add_argument("--lat", type=float, help="latitude, degrees (WGS 84, north positive)")
    p.add_argument("--lon", type=float, help="longitude, degrees (east positive)")
    p.add_argument("--height-m", type=float, help="height, metres (above mean sea level, "
                   "as a GPS shows it)")
    p.add_argument("--gps", metavar="URL", help="read NMEA GGA sentences from a GPS receiver "
                   "on a serial port or pyserial URL (sim://gps?... simulates one)")
    p.add_argument("--fixes", type=count, default=5, help="GPS fixes to average (default 5)")
    p.add_argument("--baud", type=int, default=4800, help="GPS baud rate (default 4800)")
    p.add_argument("--timeout", type=float, default=30.0,
                   help="seconds to wait for each GPS fix (default 30)")
    p.set_defaults(func=run_set_position)


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
    p.set_defaults(func=run_set_rig)


def run_set_rig(args: argparse.Namespace) -> int:
    from rigkit.capture.positioning import set_rig

    session = set_rig(args.session, args.rig)
    lb = session.rig().baseline_lb
    print(f"{session.path}: rig {session.rig().name} (C_lb {lb.value_m:.4f} +- "
          f"{lb.tolerance_m:.4f} m); process it again for results under it: "
          f"rigkit process {session.path}")
    return 0


def run_set_position(args: argparse.Namespace) -> int:
    from rigkit.capture import load_session
    from rigkit.capture.positioning import set_tripod_position
    from rigkit.errors import InputError
    from rigkit.export.georef import utm_epsg

    typed = [args.lat, args.lon, args.height_m]
    if args.gps is not None and any(v is not None for v in typed):
        raise InputError("give --lat, --lon and --height-m, or --gps, not both")
    if args.gps is None and any(v is None for v in typed):
        raise InputError("give all of --lat, --lon and --height-m, or --gps URL")
    load_session(args.session)  # a clear error for a bad session before a GPS wait
    position = _from_gps(args) if args.gps is not None else _typed(args)
    set_tripod_position(args.session, position)
    print(f"tripod at {position.lat_deg:.7f}, {position.lon_deg:.7f}, "
          f"{position.height_m:.2f} m ({position.source})")
    try:
        utm_epsg(position.lat_deg, position.lon_deg)
    except InputError as exc:  # recorded all the same: it is where the tripod stood
        print(f"warning: {exc}: `rigkit export` can place this session's points only in "
              "the camera frame (--frame camera)", file=sys.stderr)
    return 0


def _typed(args: argparse.Namespace) -> Any:
    from rigkit.capture import utc_now
    from rigkit.capture.tripod import TripodPosition

    return TripodPosition(args.lat, args.lon, args.height_m, "manual", utc_now())


def _from_gps(args: argparse.Namespace) -> Any:
    from rigkit.capture import utc_now
    from rigkit.capture.tripod import TripodPosition
    from rigkit.rangefinder.framing import escape_bytes
    from rigkit.rangefinder.gps import mean_position, open_gps

    fixes = []
    with open_gps(args.gps, baud=args.baud, timeout=args.timeout) as gps:
        for _ in range(args.fixes):
            fixes.append(gps.read())
            print(f"fix {len(fixes)}/{args.fixes}: {fixes[-1].lat_deg:.7f}, "
                  f"{fixes[-1].lon_deg:.7f}, {fixes[-1].satellites} satellites", flush=True)
    lat, lon, height = mean_position(fixes)
    return TripodPosition(lat, lon, height, f"gps:{args.gps}", utc_now(), fixes=len(fixes),
                          raw=escape_bytes(fixes[-1].raw))
