"""Running ``rigkit session set-position`` and ``set-rig`` (their arguments:
:mod:`rigkit.commands.session_position`)."""

from __future__ import annotations

import argparse
import sys

from rigkit.capture import load_session, utc_now
from rigkit.capture.positioning import set_rig, set_tripod_position
from rigkit.capture.tripod import (
    HEIGHT_GPS,
    HEIGHT_UNKNOWN,
    TripodPosition,
    check_height_datum,
)
from rigkit.errors import InputError
from rigkit.export.crs import utm_epsg, vertical_crs
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
    if args.gps is not None and any(v is not None for v in [*typed, args.height_datum]):
        raise InputError("give --lat, --lon and --height-m (and --height-datum), or --gps, "
                         "not both")
    if args.gps is None and any(v is None for v in typed):
        raise InputError("give all of --lat, --lon and --height-m, or --gps URL")
    load_session(args.session)  # a clear error for a bad session before a GPS wait
    position = _from_gps(args) if args.gps is not None else _typed(args)
    set_tripod_position(args.session, position)
    separation = ("" if position.geoid_separation_m is None
                  else f", geoid {position.geoid_separation_m:.2f} m above the ellipsoid")
    print(f"tripod at {position.lat_deg:.7f}, {position.lon_deg:.7f}, "
          f"{position.height_m:.2f} m ({position.source}; height {position.height_datum}"
          f"{separation})")
    try:
        utm_epsg(position.lat_deg, position.lon_deg)
    except InputError as exc:  # recorded all the same: it is where the tripod stood
        print(f"warning: {exc}: `rigkit export` can place this session's points only in "
              "the camera frame (--frame camera)", file=sys.stderr)
    return 0


def _typed(args: argparse.Namespace) -> TripodPosition:
    datum = HEIGHT_UNKNOWN
    if args.height_datum is not None:
        datum = check_height_datum(args.height_datum)
        if datum.startswith("EPSG:"):
            vertical_crs(datum, "--height-datum")  # one PROJ knows, before it is recorded
    return TripodPosition(args.lat, args.lon, args.height_m, "manual", utc_now(),
                          height_datum=datum)


def _from_gps(args: argparse.Namespace) -> TripodPosition:
    fixes = []
    with open_gps(args.gps, baud=args.baud, timeout=args.timeout) as gps:
        for _ in range(args.fixes):
            fixes.append(gps.read())
            print(f"fix {len(fixes)}/{args.fixes}: {fixes[-1].lat_deg:.7f}, "
                  f"{fixes[-1].lon_deg:.7f}, {fixes[-1].satellites} satellites", flush=True)
    mean = mean_position(fixes)
    return TripodPosition(mean.lat_deg, mean.lon_deg, mean.height_m, f"gps:{args.gps}",
                          utc_now(), fixes=mean.count, raw=escape_bytes(fixes[-1].raw),
                          geoid_separation_m=mean.geoid_separation_m, height_datum=HEIGHT_GPS)
