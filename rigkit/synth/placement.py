"""A synthetic session placed on the map: where its tripod stands, which way its left
camera looks, and the laser's direction to each target as a laser at the tripod would
read it from the scene's ground truth, so that ``rigkit export`` puts the session on the
map and its points can be checked against the truth there.

The scene's world frame is its left camera's (x right, y down, z forward, metres). A
placement turns it into the local east-north-up frame at the tripod: the camera looks
``azimuth_deg`` clockwise from true north, ``elevation_deg`` above the horizontal,
rolled by ``roll_deg`` (its right side down). Each target's direction is the line from
the laser's aperture (the rig's ``rangefinder.offset``) to the ray-traced point at its
pixel (the true camera: its own principal point and lens distortion), exact: no compass
or inclinometer error is simulated.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np

from rigkit.capture.actions import changing
from rigkit.capture.positioning import set_tripod_position
from rigkit.capture.session import log_event, save_session, utc_now
from rigkit.capture.tripod import (
    HEIGHT_ELLIPSOIDAL,
    HEIGHT_GPS,
    TripodPosition,
    direction_angles,
    enu_direction,
)
from rigkit.errors import InputError
from rigkit.synth.io import SceneTruth, load_scene

SIMULATED = "simulated"
"""The source of the readings a placement gives directions to: a synthetic session's
own; a reading of anything else is never changed."""


@dataclass(frozen=True)
class Placement:
    """The tripod at ``lat_deg``, ``lon_deg`` (WGS 84) and ``height_m``: above the
    ellipsoid, or, with ``geoid_separation_m``, above mean sea level as a GPS gives it
    (the geoid that far above the ellipsoid); the left camera pointing ``azimuth_deg``,
    ``elevation_deg``, ``roll_deg`` (degrees, see the module)."""

    lat_deg: float
    lon_deg: float
    height_m: float
    azimuth_deg: float = 0.0
    elevation_deg: float = 0.0
    roll_deg: float = 0.0
    geoid_separation_m: float | None = None

    def rotation(self) -> np.ndarray:
        """R (3, 3): camera-frame vectors -> ENU."""
        forward = enu_direction(self.azimuth_deg, self.elevation_deg)
        a = math.radians(self.azimuth_deg)
        right = np.array([math.cos(a), -math.sin(a), 0.0])
        down = np.cross(forward, right)
        r = math.radians(self.roll_deg)
        right, down = (math.cos(r) * right + math.sin(r) * down,
                       -math.sin(r) * right + math.cos(r) * down)
        return np.column_stack([right, down, forward])

    def tripod(self) -> TripodPosition:
        """The position a session placed so records."""
        gps = self.geoid_separation_m is not None
        return TripodPosition(
            self.lat_deg, self.lon_deg, self.height_m, SIMULATED, utc_now(),
            geoid_separation_m=self.geoid_separation_m,
            height_datum=HEIGHT_GPS if gps else HEIGHT_ELLIPSOIDAL)


def target_point(truth: SceneTruth, pixel: tuple[float, float]) -> np.ndarray:
    """The ray-traced point (3,) at ``pixel`` of the left view, camera frame, m: the
    true camera's ray there times the true depth at the nearest pixel."""
    left = truth.cameras["left"]
    u, v = pixel
    z = float(truth.depth("left")[round(v), round(u)])
    if not math.isfinite(z):
        raise InputError(f"{truth.path}: no surface at pixel ({u:g}, {v:g}) to aim at")
    ray = left.rays(np.array([float(u)]), np.array([float(v)]))[0]
    return ray * z  # the world frame is the left camera's


def true_map_points(truth: SceneTruth, placement: Placement, pixels: np.ndarray, crs: Any
                    ) -> tuple[np.ndarray, np.ndarray]:
    """The ray-traced points at left-image ``pixels`` ((n, 2) float, u, v) on the map
    ``crs`` (a projected pyproj CRS): (n, 3) easting, northing and height as the
    placement's tripod height is measured (above the ellipsoid, or a GPS's mean sea
    level), NaN where the truth has no surface; and (n, 3) unit lines of sight from the
    tripod, on the map (whose grid north is not true north). Computed apart from
    ``rigkit export``'s georeferencing, as the truth to check it against: east-north-up
    to geocentric by the WGS 84 formulas here, then PROJ to longitude, latitude and
    height and on to ``crs``."""
    import pyproj

    left = truth.cameras["left"]
    u, v = pixels[:, 0], pixels[:, 1]
    z = truth.depth("left")[np.rint(v).astype(int), np.rint(u).astype(int)].astype(np.float64)
    enu = (left.rays(u, v) * z[:, None]) @ placement.rotation().T  # world = left camera
    separation = placement.geoid_separation_m or 0.0
    lat, lon = math.radians(placement.lat_deg), math.radians(placement.lon_deg)
    h0 = placement.height_m + separation  # the tripod's height above the ellipsoid
    a, flattening = 6378137.0, 1 / 298.257223563  # WGS 84
    e2 = flattening * (2 - flattening)
    n = a / math.sqrt(1 - e2 * math.sin(lat) ** 2)
    origin = np.array([(n + h0) * math.cos(lat) * math.cos(lon),
                       (n + h0) * math.cos(lat) * math.sin(lon),
                       (n * (1 - e2) + h0) * math.sin(lat)])
    to_ecef = np.array([
        [-math.sin(lon), -math.sin(lat) * math.cos(lon), math.cos(lat) * math.cos(lon)],
        [math.cos(lon), -math.sin(lat) * math.sin(lon), math.cos(lat) * math.sin(lon)],
        [0.0, math.cos(lat), math.sin(lat)]])
    ecef = origin + enu @ to_ecef.T
    lons, lats, heights = pyproj.Transformer.from_crs(4978, 4979, always_xy=True).transform(
        ecef[:, 0], ecef[:, 1], ecef[:, 2])
    to_map = pyproj.Transformer.from_crs(4979, crs.to_3d(), always_xy=True)
    on_map = to_map.transform(lons, lats, heights)
    points = np.column_stack([on_map[0], on_map[1], heights - separation])
    tripod = to_map.transform(placement.lon_deg, placement.lat_deg, h0)
    line = points - np.array([tripod[0], tripod[1], placement.height_m])
    return points, line / np.linalg.norm(line, axis=1, keepdims=True)


def sight_errors(points: np.ndarray, truth: np.ndarray, line: np.ndarray
                 ) -> tuple[np.ndarray, np.ndarray]:
    """Exported ``points`` against their ``truth`` ((n, 3) each, m, one frame) split by
    the unit lines of sight ``line`` ((n, 3)): (n,) signed error along the line (where
    the depth's own error lies) and (n,) distance across it, m."""
    error = points - truth
    along = np.sum(error * line, axis=1)
    return along, np.linalg.norm(error - along[:, None] * line, axis=1)


def gridded_truth(points: np.ndarray, cell_m: float, west: float, north: float,
                  shape: tuple[int, int]) -> np.ndarray:
    """True ``points`` ((n, 3): easting, northing, height, m; finite) gridded as a
    north-up DSM of ``shape`` (rows, columns) whose cells of ``cell_m`` start at
    ``west``, ``north`` are: (rows, columns) the mean height of the points in each cell,
    NaN where none falls."""
    height, width = shape
    col = np.floor((points[:, 0] - west) / cell_m).astype(int)
    row = np.floor((north - points[:, 1]) / cell_m).astype(int)
    inside = (col >= 0) & (col < width) & (row >= 0) & (row < height)
    index = row[inside] * width + col[inside]
    count = np.bincount(index, minlength=height * width)
    total = np.bincount(index, points[inside, 2], minlength=height * width)
    with np.errstate(invalid="ignore", divide="ignore"):
        return (total / count).reshape(height, width)


def laser_direction(point: np.ndarray, placement: Placement,
                    aperture: tuple[float, float, float] = (0.0, 0.0, 0.0)
                    ) -> tuple[float, float]:
    """(azimuth, inclination) in degrees a laser reads for ``point`` (3,) of the camera
    frame, from ``aperture``: (right, up, forward) m of the camera, as a rig profile's
    ``rangefinder.offset`` gives it."""
    line = point - np.array([aperture[0], -aperture[1], aperture[2]])
    return direction_angles(placement.rotation() @ line)


def place_session(path: Path, placement: Placement) -> None:
    """Place the synthetic session at ``path`` (a scene folder made a session by
    ``rigkit synth --session``) on the map: record ``placement``'s tripod, and give each
    simulated reading the laser's azimuth (true north) and inclination to its target's
    ray-traced point. InputError for a folder without the scene's truth, or a reading
    that is not simulated (a real one is never changed)."""
    truth = load_scene(path)
    with changing(Path(path), "place") as session:
        spec = session.rig().rangefinder
        aperture = spec.offset_m if spec is not None and spec.offset_m is not None else (
            0.0, 0.0, 0.0)
        targets = []
        for target in session.targets:
            if any(r.source != SIMULATED for r in target.readings):
                raise InputError(f"{path}: target {target.name} has readings that are not "
                                 "simulated; only a synthetic session is placed on the map")
            azimuth, inclination = laser_direction(target_point(truth, target.pixel),
                                                   placement, aperture)
            if spec is not None and spec.azimuth == "magnetic":  # as the laser would read
                azimuth = (azimuth - spec.declination_deg) % 360.0
            readings = tuple(replace(r, azimuth_deg=round(azimuth, 6),
                                     inclination_deg=round(inclination, 6))
                             for r in target.readings)
            targets.append(replace(target, readings=readings))
        save_session(replace(session, targets=tuple(targets)))
        log_event(session.path, "place", f"synthetic: camera looks {placement.azimuth_deg:g} "
                  f"deg from north, {placement.elevation_deg:+g} deg up; laser directions "
                  "from the scene's truth")
    set_tripod_position(path, placement.tripod())
