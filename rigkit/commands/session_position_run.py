"""Running ``rigkit session set-position`` and ``set-rig`` (their arguments:
:mod:`rigkit.commands.session_position`)."""

from __future__ import annotations

import argparse
import sys

from rigkit.capture import load_session, utc_now
from rigkit.capture.positioning import set_rig, set_tripod_position
from rigkit.capture.tripod import TripodPosition
from rigkit.errors import InputError
from rigkit.export.georef import utm_epsg
from rigkit.rangefinder.framing import escape_bytes
from rigkit.rangefinder.gps import mean_position, open_gps


def run_set_rig(args: argparse.Namespace) -> int:
    session = set_rig(args.session, args.rig)
    lb = session.rig().baseline_lb
    print(f"{session.path}: rig {session.rig().name} (C_lb {lb.value_m:.4f} +- "
          f"{lb.tolerance_m:.4f} m); process it again for results under it: "
          f"rigkit process {session.path}")
    return 0


def run_set_position(args: argparse.Namespace) -> int:
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


def _typed(args: argparse.Namespace) -> TripodPosition:
    return TripodPosition(args.lat, args.lon, args.height_m, "manual", utc_now())


def _from_gps(args: argparse.Namespace) -> TripodPosition:
    fixes = []
    with open_gps(args.gps, baud=args.baud, timeout=args.timeout) as gps:
        for _ in range(args.fixes):
            fixes.append(gps.read())
            print(f"fix {len(fixes)}/{args.fixes}: {fixes[-1].lat_deg:.7f}, "
                  f"{fixes[-1].lon_deg:.7f}, {fixes[-1].satellites} satellites", flush=True)
    lat, lon, height = mean_position(fixes)
    return TripodPosition(lat, lon, height, f"gps:{args.gps}", utc_now(), fixes=len(fixes),
                          raw=escape_bytes(fixes[-1].raw))
