"""Georeferencing a depth map from what the tripod knows: its position, and the laser's
azimuth and inclination at two or more targets seen in the left image.

Frames: the camera frame is the left camera's (x right, y down, z forward, metres); ENU
is the local east-north-up frame at the tripod (metres, "up" along the WGS 84 ellipsoid's
normal); the map frame is the tripod's UTM zone (easting, northing, metres) with height
in metres (the tripod's height as recorded plus "up").

1. Each target gives two unit vectors for one direction: its pixel's ray in the camera
   frame (the pinhole intrinsics the laser comparison uses) and the laser's line of sight
   in ENU from its azimuth (made true with the rig profile's declination) and
   inclination, averaged over the target's readings.
2. The rotation R (camera -> ENU) that best maps the rays onto the lines of sight is
   Wahba's problem (G. Wahba, SIAM Review 7, 1965), solved by the singular value
   decomposition as in W. Kabsch, Acta Cryst. A32, 1976: a proper rotation (det +1).
   Its residual (the angle left between each mapped ray and its line of sight) says
   how well the directions agree; too large, or directions too close together to fix
   the roll about the optical axis, and georeferencing is refused.
3. A point p (camera frame) lands at ENU R p from the tripod, and in the map through PROJ
   (topocentric -> geocentric -> UTM: exact, meridian convergence and scale included).

The laser's offset from the camera (rig profile ``rangefinder.offset``, ~0.1 m) is not
applied: at 200 m it turns a line of sight by under 0.03 degrees.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cached_property
from typing import Any

import numpy as np

from rigkit.capture.model import Session
from rigkit.capture.tripod import TripodPosition
from rigkit.errors import InputError
from rigkit.export.points import camera_rays
from rigkit.export.source import DepthMap

MAX_RESIDUAL_DEG = 1.5
"""A target whose line of sight misses its fitted ray by more than this stops the
export: a typing error, a swapped target, a magnetic disturbance."""
MIN_SPREAD_FRACTION = 0.25
MIN_SPREAD_DEG = 2.0
"""The targets' directions must span min(MIN_SPREAD_DEG, MIN_SPREAD_FRACTION x the
diagonal field of view): the roll about the optical axis rests on their spread."""


@dataclass(frozen=True)
class Sighting:
    """One target's direction twice: ``camera`` (3,) unit vector in the camera frame
    from its pixel, ``enu`` (3,) unit vector in ENU from the laser."""

    name: str
    camera: np.ndarray
    enu: np.ndarray


def enu_direction(azimuth_deg: float, inclination_deg: float) -> np.ndarray:
    """(east, north, up) unit vector of a line of sight ``azimuth_deg`` clockwise from
    true north and ``inclination_deg`` above the horizontal."""
    a, i = math.radians(azimuth_deg), math.radians(inclination_deg)
    return np.array([math.cos(i) * math.sin(a), math.cos(i) * math.cos(a), math.sin(i)])


def sightings(session: Session, f: float, cx: float, cy: float) -> list[Sighting]:
    """The targets whose readings carry both azimuth and inclination, each direction
    the mean of its readings' (azimuths corrected to true north by the rig profile)."""
    spec = session.rig().rangefinder
    found = []
    for target in session.targets:
        shots = [(r.azimuth_deg, r.inclination_deg) for r in target.readings
                 if r.azimuth_deg is not None and r.inclination_deg is not None]
        if not shots:
            continue
        enu = sum(enu_direction(spec.true_azimuth_deg(a) if spec else a, i) for a, i in shots)
        ray = camera_rays(np.array(target.pixel[0]), np.array(target.pixel[1]), f, cx, cy)
        found.append(Sighting(target.name, _unit(ray), _unit(np.asarray(enu))))
    return found


def _unit(vector: np.ndarray) -> np.ndarray:
    return vector / np.linalg.norm(vector)


def wahba_rotation(camera: np.ndarray, enu: np.ndarray) -> np.ndarray:
    """The proper rotation R (3, 3) minimising sum |R a_i - b_i|^2 over the rows a_i of
    ``camera`` and b_i of ``enu`` ((n, 3) unit vectors, n >= 2 not all parallel): with
    H = sum a_i b_i^T = U S V^T, R = V diag(1, 1, d) U^T, d = det(V U^T) = +-1 (Kabsch)."""
    u, _, vt = np.linalg.svd(camera.T @ enu)
    d = np.sign(np.linalg.det(vt.T @ u.T))
    return vt.T @ np.diag([1.0, 1.0, d]) @ u.T


def _angle_deg(a: np.ndarray, b: np.ndarray) -> float:
    """Angle between unit vectors, degrees (atan2: accurate for small angles too)."""
    return math.degrees(math.atan2(np.linalg.norm(np.cross(a, b)), float(a @ b)))


def _spread_deg(vectors: list[np.ndarray]) -> float:
    return max(_angle_deg(a, b) for i, a in enumerate(vectors) for b in vectors[i + 1:])


@dataclass(frozen=True)
class Orientation:
    """The left camera's orientation: ``rotation`` (3, 3) maps camera-frame vectors to
    ENU; ``residuals_deg`` per target (``names``), degrees; ``spread_deg`` the widest
    angle between two targets' directions."""

    rotation: np.ndarray
    names: tuple[str, ...]
    residuals_deg: tuple[float, ...]
    spread_deg: float

    @property
    def rms_residual_deg(self) -> float:
        return math.sqrt(sum(r * r for r in self.residuals_deg) / len(self.residuals_deg))

    def pointing(self) -> tuple[float, float, float]:
        """(azimuth from true north, elevation, roll) of the camera, degrees; roll is the
        image x axis's tilt, positive when its right side is lower."""
        east, north, up = self.rotation[:, 2]
        right = self.rotation[:, 0]
        return (math.degrees(math.atan2(east, north)) % 360.0, math.degrees(math.asin(up)),
                -math.degrees(math.asin(right[2])))


def half_sighted(session: Session) -> list[str]:
    """The targets georeferencing leaves out although a reading has half a direction:
    "T3 has an azimuth but no inclination" (or the other way round)."""
    notes = []
    for target in session.targets:
        readings = target.readings
        if any(r.azimuth_deg is not None and r.inclination_deg is not None for r in readings):
            continue
        if any(r.azimuth_deg is not None for r in readings):
            notes.append(f"{target.name} has an azimuth but no inclination")
        elif any(r.inclination_deg is not None for r in readings):
            notes.append(f"{target.name} has an inclination but no azimuth")
    return notes


def orient_camera(session: Session, source: DepthMap,
                  max_residual_deg: float = MAX_RESIDUAL_DEG) -> Orientation:
    """Solve the left camera's orientation from the session's targets; InputError (one
    line) when fewer than two targets have directions, they lie too close together, or
    one misses by more than ``max_residual_deg``."""
    found = sightings(session, source.f, source.cx, source.cy)
    if len(found) < 2:
        half = "".join(f"; {note}" for note in half_sighted(session))
        raise InputError(
            f"{session.path}: georeferencing needs 2 or more targets with a laser azimuth "
            f"and inclination, {len(found)} have them{half} (rigkit session add-target ... "
            "--azimuth DEG --inclination DEG), or export with --frame camera")
    width, height = source.size
    fov = 2 * math.degrees(math.atan(math.hypot(width, height) / 2 / source.f))
    needed = min(MIN_SPREAD_DEG, MIN_SPREAD_FRACTION * fov)
    spread = min(_spread_deg([s.camera for s in found]), _spread_deg([s.enu for s in found]))
    if spread < needed:
        raise InputError(
            f"{session.path}: the targets' directions span {spread:.2f} deg, under the "
            f"{needed:.2f} deg needed to fix the camera's roll; add a target near another "
            "corner of the image")
    camera, enu = np.array([s.camera for s in found]), np.array([s.enu for s in found])
    rotation = wahba_rotation(camera, enu)
    residuals = tuple(_angle_deg(rotation @ s.camera, s.enu) for s in found)
    worst = int(np.argmax(residuals))
    if residuals[worst] > max_residual_deg:
        raise InputError(
            f"{session.path}: target {found[worst].name}'s laser direction misses its pixel "
            f"by {residuals[worst]:.2f} deg after the best fit (limit {max_residual_deg:g}"
            " deg): check its azimuth, inclination and pixel, and the rig's declination")
    return Orientation(rotation, tuple(s.name for s in found), residuals, spread)


def utm_epsg(lat_deg: float, lon_deg: float) -> int:
    """EPSG code of the WGS 84 UTM zone holding (lat, lon): 326zz north, 327zz south
    (the zone by longitude alone, without Norway's and Svalbard's exceptions, which is as
    exact a projection there); InputError outside UTM's 80 S to 84 N."""
    if not -80.0 <= lat_deg <= 84.0:
        raise InputError(f"latitude {lat_deg:.7g}: UTM covers 80 S to 84 N only")
    zone = min(int((lon_deg + 180.0) // 6.0) + 1, 60)
    return (32600 if lat_deg >= 0 else 32700) + zone


@dataclass(frozen=True)
class Georeference:
    """Where the camera frame lies on the map: the tripod's ``position`` and the
    camera's ``orientation``; ``epsg`` its UTM zone's code."""

    position: TripodPosition
    orientation: Orientation
    epsg: int
    left_out: tuple[str, ...] = ()
    """Targets left out for half a direction (:func:`half_sighted`)."""

    @property
    def crs(self) -> Any:
        """The map's pyproj CRS (WGS 84 / UTM zone ...)."""
        import pyproj

        return pyproj.CRS.from_epsg(self.epsg)

    @cached_property
    def _to_utm(self) -> Any:
        import pyproj

        p = self.position
        zone, south = self.epsg % 100, " +south" if self.epsg >= 32700 else ""
        return pyproj.Transformer.from_pipeline(
            "+proj=pipeline "
            f"+step +inv +proj=topocentric +ellps=WGS84 +lat_0={p.lat_deg!r} "
            f"+lon_0={p.lon_deg!r} +h_0={p.height_m!r} "
            "+step +inv +proj=cart +ellps=WGS84 "
            f"+step +proj=utm +zone={zone}{south} +ellps=WGS84")

    def enu_to_map(self, enu: np.ndarray) -> np.ndarray:
        """(n, 3) ENU metres from the tripod -> (n, 3) easting, northing, height, m."""
        east, north, height = self._to_utm.transform(enu[:, 0], enu[:, 1], enu[:, 2])
        return np.column_stack([east, north, height])

    def to_map(self, xyz: np.ndarray) -> np.ndarray:
        """(n, 3) camera-frame points, m -> (n, 3) map coordinates (a point Transform)."""
        return self.enu_to_map(xyz @ self.orientation.rotation.T)

    @property
    def origin(self) -> tuple[float, float, float]:
        """The tripod on the map: easting, northing, height, m."""
        e, n, h = self.enu_to_map(np.zeros((1, 3)))[0]
        return float(e), float(n), float(h)


def georeference(source: DepthMap, max_residual_deg: float = MAX_RESIDUAL_DEG
                 ) -> Georeference:
    """The georeference of a session's depth map; InputError when the session has no
    tripod position or its orientation cannot be solved (see :func:`orient_camera`)."""
    session = source.session
    if session is None:
        raise InputError(f"{source.name}: a depth map file has no tripod position; export "
                         "the session to georeference it")
    position = session.tripod
    if position is None:
        raise InputError(f"{session.path}: no tripod position (rigkit session set-position)")
    orientation = orient_camera(session, source, max_residual_deg)
    return Georeference(position, orientation, utm_epsg(position.lat_deg, position.lon_deg),
                        tuple(half_sighted(session)))
