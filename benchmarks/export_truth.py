"""How far the exported points and DSM cells lie from the truth, on the map: the bundled
example (a distorting scene placed at 46.55 N 7.98 E, rigkit.synth.placement),
processed, exported in its UTM zone and in Swiss LV95.

    python -m benchmarks.export_truth --work out/bench-export-truth [--step 1]

For each LAS point, its error along the line of sight against its stated sigma (the
share within 1, 2 and 3 sigma; a Gaussian error gives 68, 95 and 99.7 %) and its
distance across it; for each DSM cell with truth, its elevation's error against its
sigma band, the truth gridded as the DSM is (the mean height of the true points whose
true place falls in the cell). The truth is placed on the map apart from rigkit's
georeferencing (rigkit.synth.placement.true_map_points).
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import laspy
import numpy as np
import pyproj
import rasterio

from benchmarks.common import OUT, processed_example
from rigkit.export import MapRequest, export_path
from rigkit.synth import load_scene
from rigkit.synth.placement import (
    Placement,
    gridded_truth,
    sight_errors,
    true_map_points,
)

PLACEMENT = Placement(46.55123, 7.98456, 1012.0, 47.3, -50.0, 0.0, 49.6)
"""How capture/example was placed."""


def shares(ratio: np.ndarray) -> str:
    return " / ".join(f"{100 * float((ratio <= k).mean()):.1f}" for k in (1, 2, 3))


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--work", type=Path, default=OUT / "bench-export-truth")
    parser.add_argument("--step", type=int, default=1)
    args = parser.parse_args(argv)
    session = processed_example(args.work)
    step = args.step
    depth = np.load(session / "results" / "depth.npy")[::step, ::step]
    sigma = np.load(session / "results" / "sigma.npy")[::step, ::step]
    rows, cols = np.nonzero(np.isfinite(depth))
    pixels = np.column_stack([cols * step, rows * step]).astype(np.float64)
    truth = load_scene(session)
    rays = truth.cameras["left"].rays(pixels[:, 0], pixels[:, 1])
    stated = sigma[rows, cols] * np.linalg.norm(rays, axis=1)
    print(f"capture/example, step {step}: {len(pixels)} points")
    print("CRS          LAS along: % within 1/2/3 sigma   across mm p50/p99   "
          "DSM cells: % within 1/2/3 sigma   cells   export s")
    for epsg in (32632, 2056):
        out = args.work / f"epsg-{epsg}"
        t0 = time.perf_counter()
        export_path(session, out, ["las", "dsm"], step=step,
                    request=MapRequest(crs=None if epsg == 32632 else f"EPSG:{epsg}"))
        seconds = time.perf_counter() - t0
        points, line = true_map_points(truth, PLACEMENT, pixels, pyproj.CRS.from_epsg(epsg))
        known = np.isfinite(points[:, 2])
        las = laspy.read(out / "example.las")
        along, across = sight_errors(np.column_stack([las.x, las.y, las.z])[known],
                                     points[known], line[known])
        across *= 1000
        with rasterio.open(out / "example.dsm.tif") as dsm:
            elevation = dsm.read(1, masked=True).filled(np.nan)
            band = dsm.read(2, masked=True).filled(np.nan)
            cell, west, north = dsm.transform.a, dsm.transform.c, dsm.transform.f
        true_cells = gridded_truth(points[known], cell, west, north, elevation.shape)
        both = np.isfinite(true_cells) & np.isfinite(elevation)
        ratio = np.abs(elevation - true_cells)[both] / band[both]
        print(f"EPSG:{epsg:<6} {shares(np.abs(along) / stated[known]):>28}   "
              f"{np.median(across):6.1f} / {np.percentile(across, 99):5.1f}   "
              f"{shares(ratio):>30}   {both.sum():6d}   {seconds:6.1f}")
        print(f"             DSM: cell {cell:g} m, median |error| "
              f"{np.median(np.abs(elevation - true_cells)[both]):.3f} m, median sigma "
              f"{np.median(band[both]):.3f} m; LAS: median |error| along "
              f"{np.median(np.abs(along)):.3f} m, median sigma {np.median(stated):.3f} m")
    return 0


if __name__ == "__main__":
    sys.exit(main())
