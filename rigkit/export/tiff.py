"""The depth map as a float32 TIFF raster in the left image's pixel grid: band 1 depth,
band 2 sigma, NaN where there is no depth (the GDAL_NODATA tag says so), compressed
(DEFLATE with the floating-point predictor), with the rig, units and lens as JSON in its
ImageDescription.

Written through rasterio (GDAL), strip by strip, so only one strip is in memory at a
time; GDAL is also what writes the map raster (:mod:`rigkit.export.dsm`). QGIS shows it
as a two-band raster with no map position (it is an image, not a map); Fiji/ImageJ,
Python (rasterio, tifffile) and MATLAB read it.
"""

from __future__ import annotations

import contextlib
import json
import warnings
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import numpy as np

from rigkit.export.source import DepthMap

ROWS_PER_STRIP = 64


@contextlib.contextmanager
def gdal_env() -> Iterator[None]:
    """GDAL as rigkit writes with it: no ``.aux.xml`` beside a file (the staged folder
    holds exactly the export's files)."""
    import rasterio

    with rasterio.Env(GDAL_PAM_ENABLED="NO"):
        yield


def tiff_metadata(source: DepthMap) -> dict[str, Any]:
    """What the TIFF says about itself (JSON in its ImageDescription)."""
    lens = source.lens
    return {
        "bands": ["depth_m", "sigma_m"],
        "units": "metres; depth is z along the left camera's optical axis, NaN = none",
        "pixel_convention": "pixel centres at integers; (0, 0) is the top-left pixel",
        "rig": source.rig,
        "lens": {"focal_px": lens.focal_px, "distortion_k1_k2_p1_p2_k3": list(lens.distortion),
                 "centre_shift_px": list(lens.shift), "source": source.run.lens_source},
        "run_id": source.run_id,
        "software": "rigkit export",
    }


def write_tiff(path: Path, source: DepthMap, progress: Callable[[float], None] | None = None
               ) -> None:
    """Write ``source``'s depth and sigma to ``path`` ((2, H, W) float32);
    ``progress(fraction)`` is called per strip."""
    import rasterio
    from rasterio.errors import NotGeoreferencedWarning
    from rasterio.windows import Window

    height, width = source.depth.shape
    report = progress or (lambda fraction: None)
    strips = -(-height // ROWS_PER_STRIP)
    profile = {"driver": "GTiff", "width": width, "height": height, "count": 2,
               "dtype": "float32", "nodata": float("nan"), "compress": "deflate",
               "predictor": 3, "interleave": "band", "tiled": False,
               "blockysize": ROWS_PER_STRIP}
    with gdal_env(), warnings.catch_warnings():
        warnings.simplefilter("ignore", NotGeoreferencedWarning)  # an image, not a map
        with rasterio.open(path, "w", **profile) as dst:
            dst.update_tags(TIFFTAG_IMAGEDESCRIPTION=json.dumps(tiff_metadata(source)))
            dst.descriptions = ("depth_m", "sigma_m")
            dst.units = ("metre", "metre")
            for band, values in enumerate((source.depth, source.sigma)):
                for i, top in enumerate(range(0, height, ROWS_PER_STRIP)):
                    rows = min(ROWS_PER_STRIP, height - top)
                    dst.write(np.asarray(values[top:top + rows], np.float32), band + 1,
                              window=Window(0, top, width, rows))
                    report((band * strips + i + 1) / (2 * strips))
