"""``rigkit export``: a depth map as point clouds (PLY, LAS, LAZ), a TIFF raster and a
map raster (DSM)."""

from __future__ import annotations

import argparse
from pathlib import Path

from rigkit.commands import count, finite, output_folder, within
from rigkit.export.defaults import VERTICAL_ELLIPSOIDAL, VERTICAL_RECORDED

EXAMPLE = """examples:
  rigkit export capture/example --out out/example-cloud
  rigkit export capture/example --out out/example-map --format las,dsm --crs EPSG:2056
  rigkit export capture/ridge-0412 --out out/ridge --format ply,laz,tif --step 4
  rigkit export out/depth.npy --out out/cloud            # rigkit depth's output

A point per estimated pixel (NaN skipped; --step N keeps every N-th row and column): its
position, the left image's grey value (PLY red/green/blue, LAS intensity and RGB), the
depth's 1-sigma error (PLY property and LAS extra bytes "sigma", metres) and whether the
depth was filled from a neighbour (PLY property "filled", LAS synthetic bit). Positions
are in the left camera's frame (x right, y down, z forward, metres) unless the session
has a tripod position (rigkit session set-position) and 2 or more targets with a laser
azimuth and inclination: then on the map, in the tripod's UTM zone or --crs, heights as
--vertical says (a compound CRS in the LAS and DSM files).
tif: depth and sigma as a two-band float32 raster in the image's pixel grid.
dsm: a north-up elevation raster on the map (Cloud-Optimized GeoTIFF, bands elevation and
sigma, nodata -9999), cells from the points' spacing or --cell.
Files: OUT/NAME.ply, .las, .laz, .tif, .dsm.tif and NAME.export.json (the run, CRS,
orientation fit and error budget), written together or not at all (docs/outputs.md).
"""


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "export",
        help="a session's or depth map's points as PLY, LAS/LAZ (georeferenced), TIFF "
        "and a DSM",
        description="Export a depth map for CloudCompare, MeshLab or QGIS: point clouds "
        "in the camera frame or on the map, a float32 raster and a map raster "
        "(docs/outputs.md).",
        epilog=EXAMPLE,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("source", type=Path, metavar="SESSION|DEPTH.npy",
                   help="a processed session folder, or a depth map written by rigkit depth")
    p.add_argument("--out", type=output_folder, required=True, help="folder to write into")
    p.add_argument("--format", default="ply,las",
                   help="comma-separated: ply, las, laz, tif, dsm (default: ply,las)")
    p.add_argument("--step", type=count, default=1,
                   help="keep every N-th row and column of points (default 1: all)")
    p.add_argument("--frame", choices=("auto", "camera", "map"), default="auto",
                   help="camera: the left camera's frame; map: on the map (refused if it "
                   "cannot be solved); auto (default): on the map when the session has a "
                   "tripod position and its orientation can be solved, else the camera "
                   "frame, saying why")
    p.add_argument("--crs", metavar="EPSG:CODE",
                   help="the map's projected CRS, any PROJ knows (e.g. EPSG:2056 for Swiss "
                   "LV95; default: the tripod's WGS 84 UTM zone)")
    p.add_argument("--vertical", metavar=f"{VERTICAL_RECORDED}|{VERTICAL_ELLIPSOIDAL}|EPSG:CODE",
                   default=VERTICAL_RECORDED,
                   help=f"what heights are: {VERTICAL_RECORDED} (default: as the tripod's "
                   "height was recorded, e.g. a GPS's mean sea level), "
                   f"{VERTICAL_ELLIPSOIDAL}, or a vertical CRS PROJ can transform to (e.g. "
                   "EPSG:5728 LN02; its geoid grid needed)")
    p.add_argument("--cell", type=finite, metavar="SIZE",
                   help="the DSM's cell size in the CRS's unit (default: from the points' "
                   "spacing)")
    p.add_argument("--max-residual-deg", type=within(0.0, 180.0, "degrees", low_open=True),
                   help="largest angle a target's laser direction may miss its pixel by "
                   "after the orientation fit (default 1.5)")
    p.add_argument("--quiet", action="store_true", help="no progress output")
    p.set_defaults(runner="rigkit.commands.export_run:run")
