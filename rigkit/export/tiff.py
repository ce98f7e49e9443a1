"""The depth map as a float32 TIFF raster: band 1 depth, band 2 sigma, in the left
image's pixel grid, with the rig, units and intrinsics as JSON in its ImageDescription.

Written strip by strip through tifffile (two planes, planar configuration "separate"),
so only one strip is in memory at a time. QGIS shows it as a two-band raster (with no
map position: it is an image, not a map); Fiji/ImageJ, Python (tifffile, rasterio) and
MATLAB read it.
"""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import tifffile

from rigkit.export.source import DepthMap

ROWS_PER_STRIP = 64


def tiff_metadata(source: DepthMap) -> dict[str, Any]:
    """What the TIFF says about itself (JSON in its ImageDescription)."""
    return {
        "bands": ["depth_m", "sigma_m"],
        "units": "metres; depth is z along the left camera's optical axis, NaN = none",
        "pixel_convention": "pixel centres at integers; (0, 0) is the top-left pixel",
        "rig": source.rig,
        "left_camera_px": {"f": source.f, "cx": source.cx, "cy": source.cy},
        "run_id": source.run_id,
        "software": "rigkit export",
    }


def write_tiff(path: Path, source: DepthMap, progress: Any = None) -> None:
    """Write ``source``'s depth and sigma to ``path`` ((2, H, W) float32);
    ``progress(fraction)`` is called per strip."""
    height, width = source.depth.shape
    strips_per_band = -(-height // ROWS_PER_STRIP)
    report = progress or (lambda fraction: None)

    def strips() -> Iterator[np.ndarray]:
        for band, values in enumerate((source.depth, source.sigma)):
            for i, top in enumerate(range(0, height, ROWS_PER_STRIP)):
                report((band * strips_per_band + i + 1) / (2 * strips_per_band))
                yield np.asarray(values[top:top + ROWS_PER_STRIP], np.float32)

    tifffile.imwrite(path, strips(), shape=(2, height, width), dtype=np.float32,
                     photometric="minisblack", planarconfig="separate",
                     rowsperstrip=ROWS_PER_STRIP, metadata=tiff_metadata(source))
