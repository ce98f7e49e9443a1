"""Exporting depth maps for other tools: point clouds (PLY; LAS and LAZ for GIS), a
float32 TIFF raster in the image's grid and a map raster (a DSM as a Cloud-Optimized
GeoTIFF), in the left camera's frame or georeferenced (the tripod's UTM zone or any
projected CRS, heights with their datum) from the tripod's position and the laser's
directions to the targets, each export with a metadata file (docs/outputs.md).

Its public names are imported on first use (:mod:`rigkit.core.lazy`).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from rigkit.core.lazy import exports

if TYPE_CHECKING:
    from rigkit.export.georef import (
        Georeference,
        NotOnMap,
        Orientation,
        georeference,
        orient_camera,
    )
    from rigkit.export.run import (
        DEFAULT_FORMATS,
        EXPORT_DIR,
        FORMATS,
        Exported,
        MapRequest,
        export_depth,
        export_path,
        parse_formats,
    )
    from rigkit.export.source import DepthMap, open_depth

__all__ = [
    "DEFAULT_FORMATS",
    "EXPORT_DIR",
    "FORMATS",
    "DepthMap",
    "Exported",
    "Georeference",
    "MapRequest",
    "NotOnMap",
    "Orientation",
    "export_depth",
    "export_path",
    "georeference",
    "open_depth",
    "orient_camera",
    "parse_formats",
]

__getattr__ = exports(__name__, {
    "DEFAULT_FORMATS": "run",
    "DepthMap": "source",
    "EXPORT_DIR": "run",
    "Exported": "run",
    "FORMATS": "run",
    "Georeference": "georef",
    "MapRequest": "run",
    "NotOnMap": "georef",
    "Orientation": "georef",
    "export_depth": "run",
    "export_path": "run",
    "georeference": "georef",
    "open_depth": "source",
    "orient_camera": "georef",
    "parse_formats": "run",
})
