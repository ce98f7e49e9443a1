"""``rigkit export``: a depth map as point clouds (PLY, LAS, LAZ) and a TIFF raster."""

from __future__ import annotations

import argparse
from pathlib import Path

from rigkit.commands import count, finite, output_folder

EXAMPLE = """examples:
  rigkit export capture/example --out out/example-cloud
  rigkit export capture/ridge-0412 --out out/ridge --format ply,laz,tif --step 4
  rigkit export out/depth.npy --out out/cloud            # rigkit depth's output

A point per estimated pixel (NaN skipped; --step N keeps every N-th row and column): its
position, the left image's grey value (PLY red/green/blue, LAS intensity and RGB) and the
depth's 1-sigma error (PLY property and LAS extra bytes "sigma", metres). Positions are in
the left camera's frame (x right, y down, z forward, metres) unless the session has a
tripod position (rigkit session set-position) and 2 or more targets with a laser azimuth
and inclination: then on the map, in the tripod's UTM zone (the CRS in the LAS file).
tif: depth and sigma as a two-band float32 raster in the image's pixel grid.
Files: OUT/NAME.ply, .las, .laz, .tif, written together or not at all (docs/outputs.md).
"""


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "export",
        help="a session's or depth map's points as PLY, LAS/LAZ (georeferenced) and TIFF",
        description="Export a depth map for CloudCompare, MeshLab or QGIS: point clouds "
        "in the camera frame or on the map, and a float32 raster (docs/outputs.md).",
        epilog=EXAMPLE,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("source", type=Path, metavar="SESSION|DEPTH.npy",
                   help="a processed session folder, or a depth map written by rigkit depth")
    p.add_argument("--out", type=output_folder, required=True, help="folder to write into")
    p.add_argument("--format", default="ply,las",
                   help="comma-separated: ply, las, laz, tif (default: ply,las)")
    p.add_argument("--step", type=count, default=1,
                   help="keep every N-th row and column of points (default 1: all)")
    p.add_argument("--frame", choices=("auto", "camera", "map"), default="auto",
                   help="camera: the left camera's frame; map: the tripod's UTM zone "
                   "(refused if it cannot be solved); auto (default): map when the session "
                   "has a tripod position")
    p.add_argument("--max-residual-deg", type=finite,
                   help="largest angle a target's laser direction may miss its pixel by "
                   "after the orientation fit (default 1.5)")
    p.add_argument("--quiet", action="store_true", help="no progress output")
    p.set_defaults(runner="rigkit.commands.export_run:run")
