"""The metadata written beside every export (``NAME.export.json``): the run and rig the
depth map came from, the frame or CRS (what the heights are, PROJ's transformation and
its accuracy), the tripod, the orientation fit with its residuals and covariance, the
error budget at the median range, the DSM's grid, and the files.

Plain JSON, one document, keys in a fixed order; numbers in SI units unless the key says
otherwise (``_deg``, ``_rad2``, ``_px``; map coordinates in the CRS's unit).
"""

from __future__ import annotations

import json
import math
from typing import Any

import numpy as np

from rigkit import __version__
from rigkit.export.georef import (
    AZIMUTH_SIGMA_DEG,
    INCLINATION_SIGMA_DEG,
    Georeference,
)
from rigkit.export.source import DepthMap

SIDECAR_SUFFIX = ".export.json"


def dumps(document: dict[str, Any]) -> str:
    """``document`` as JSON text, a number that is not finite written as null."""
    return json.dumps(_finite(document), indent=2, allow_nan=False) + "\n"


def _finite(value: Any) -> Any:
    if isinstance(value, float) and not math.isfinite(value):
        return None
    if isinstance(value, dict):
        return {key: _finite(item) for key, item in value.items()}
    if isinstance(value, list | tuple):
        return [_finite(item) for item in value]
    return value


def camera_frame_dict(note: str | None) -> dict[str, Any]:
    return {"frame": "camera",
            "axes": "left camera: x right, y down, z forward, metres, origin at its "
                    "optical centre",
            "why_not_on_the_map": note}


def map_dict(georef: Georeference) -> dict[str, Any]:
    """The CRS, the transformation and the tripod."""
    on_map, position = georef.map, georef.position
    wkt1, wkt1_note = on_map.wkt1()
    east, north, height = georef.origin
    return {
        "frame": "map",
        "crs": {"name": on_map.name, "horizontal": on_map.horizontal_code,
                "horizontal_unit_m": on_map.unit_m, "vertical": on_map.vertical_name,
                "heights": on_map.heights,
                "gps_geoid_separation_m": on_map.geoid_separation_m,
                "wkt2": on_map.crs.to_wkt(), "wkt1": wkt1, "wkt1_note": wkt1_note},
        "transformation": {"from": "WGS 84 (EPSG:4979) longitude, latitude, ellipsoidal "
                                   "height, after the local east-north-up frame at the "
                                   "tripod (exact)",
                           "operation": on_map.operation, "accuracy_m": on_map.accuracy_m,
                           "notes": list(on_map.notes)},
        "tripod": {"lat_deg": position.lat_deg, "lon_deg": position.lon_deg,
                   "height_m": position.height_m, "height_datum": position.height_datum,
                   "geoid_separation_m": position.geoid_separation_m,
                   "source": position.source, "time_utc": position.time_utc,
                   "fixes": position.fixes, "on_map": [east, north, height]},
    }


def orientation_dict(georef: Georeference) -> dict[str, Any]:
    """The orientation fit: rotation, pointing and their uncertainty, residuals."""
    fit = georef.orientation
    azimuth, elevation, roll = fit.pointing()
    sigmas = fit.pointing_sigma_deg()
    return {
        "method": "Wahba's problem solved by SVD (Kabsch), targets' pixel rays onto the "
                  "laser's lines of sight",
        "rotation_camera_to_enu": fit.rotation.tolist(),
        "pointing_deg": {"azimuth": azimuth, "elevation": elevation, "roll": roll},
        "pointing_sigma_deg": dict(zip(("azimuth", "elevation", "roll"), sigmas,
                                       strict=True)),
        "covariance_rad2_enu": fit.covariance.tolist(),
        "covariance_from": {"azimuth_sigma_deg": AZIMUTH_SIGMA_DEG,
                            "inclination_sigma_deg": INCLINATION_SIGMA_DEG,
                            "per": "reading, averaged over a target's readings"},
        "targets": [{"name": name, "residual_deg": r}
                    for name, r in zip(fit.names, fit.residuals_deg, strict=True)],
        "rms_residual_deg": fit.rms_residual_deg,
        "spread_deg": fit.spread_deg,
        "left_out": list(georef.left_out),
    }


def error_budget(source: DepthMap, georef: Georeference | None, step: int) -> dict[str, Any]:
    """One sigma of each error source at the median range of the exported points, m."""
    depth = np.asarray(source.depth[::step, ::step])
    sigma = np.asarray(source.sigma[::step, ::step])
    known = np.isfinite(depth) & (depth > 0)
    median_z = float(np.median(depth[known])) if known.any() else math.nan
    median_sigma = float(np.median(sigma[known])) if known.any() else math.nan
    budget: dict[str, Any] = {
        "median_depth_m": median_z,
        "depth_sigma_m": {"value": median_sigma, "direction": "along the line of sight",
                          "note": "each point's own is its sigma"},
        "depth_offset_fraction": {"value": source.run.offset_depth_fraction,
                                  "note": "the part of the depth error common to every "
                                          "point at a depth (the disparity offset's)"},
        "lens": {"source": source.run.lens_source,
                 "note": "pixels are back-projected through this lens"},
    }
    if georef is None:
        return budget
    lens = source.lens
    width, height = source.size
    centre = lens.rays(np.array([[(width - 1) / 2, (height - 1) / 2]]))[0]
    corner = lens.rays(np.array([[0.0, 0.0]]))[0]
    fit, position = georef.orientation, georef.position
    budget["orientation_m"] = {
        "centre": median_z * float(np.linalg.norm(centre)) * fit.sideways_sigma(centre),
        "corner": median_z * float(np.linalg.norm(corner)) * fit.sideways_sigma(corner),
        "direction": "across the line of sight",
        "note": "from the instruments' accuracy (covariance_from); a wrong declination "
                "turns every point alike and is not in it"}
    budget["tripod_position_m"] = {
        "value": None,
        "source": position.source,
        "note": "the position's accuracy is its source's (a handheld GPS +-2-5 m, RTK "
                "+-0.02 m; typed: as good as where it came from); every point moves with it"}
    budget["transformation_m"] = {"value": georef.map.accuracy_m,
                                  "operation": georef.map.operation}
    return budget


def sidecar(source: DepthMap, georef: Georeference | None, *, note: str | None, step: int,
            points: int, filled: int | None, files: list[str],
            dsm: dict[str, Any] | None, time_utc: str) -> dict[str, Any]:
    """The whole document."""
    return {
        "software": f"rigkit {__version__} export",
        "time_utc": time_utc,
        "source": source.name,
        "files": files,
        "points": {"count": points, "step": step,
                   "filled": filled,
                   "filled_note": None if filled is not None else
                   "not known: the results hold no flags.npy (processed before rigkit "
                   "wrote it); process the session again to mark them",
                   "per_point": {"sigma": "the depth's one standard error, m, along the "
                                          "line of sight",
                                 "filled": "PLY property filled = 1 and LAS synthetic "
                                           "bit: the depth was filled from a neighbour"}},
        "run": source.run.as_dict(),
        "place": camera_frame_dict(note) if georef is None else map_dict(georef),
        "orientation": None if georef is None else orientation_dict(georef),
        "error_budget": error_budget(source, georef, step),
        "dsm": dsm,
    }
