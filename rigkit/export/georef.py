"""Georeferencing a depth map from what the tripod knows: its position, and the laser's
azimuth and inclination at two or more targets seen in the left image.

Frames: the camera frame is the left camera's (x right, y down, z forward, metres); ENU
is the local east-north-up frame at the tripod (metres, "up" along the WGS 84 ellipsoid's
normal); the map is a projected CRS (the tripod's UTM zone unless another is asked for)
with heights measured as :mod:`rigkit.export.crs` says.

1. Each target gives two unit vectors for one direction: its pixel's ray in the camera
   frame (back-projected through the run's lens, :attr:`DepthMap.lens`, as every point
   and the laser comparison are) and the laser's line of sight in ENU from its azimuth
   (made true with the rig profile's declination) and inclination, averaged over the
   target's readings.
2. The rotation R (camera -> ENU) that best maps the rays onto the lines of sight is
   Wahba's problem (G. Wahba, SIAM Review 7, 1965), solved by the singular value
   decomposition as in W. Kabsch, Acta Cryst. A32, 1976: a proper rotation (det +1).
   Its residual (the angle left between each mapped ray and its line of sight) says
   how well the directions agree; too large, or directions too close together to fix
   the roll about the optical axis, and georeferencing is refused. Its covariance
   follows from the instruments' accuracy (:func:`orientation_covariance`).
3. A point p (camera frame) lands at ENU R p from the tripod, and on the map through
   PROJ: topocentric -> geocentric -> WGS 84 longitude, latitude and height (exact), then
   PROJ's transformation to the map's CRS (exact for UTM; a datum shift's own accuracy
   for another datum, stated with the export).

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
from rigkit.capture.tripod import TripodPosition, enu_direction
from rigkit.errors import InputError
from rigkit.export.crs import MapCrs, map_crs
from rigkit.export.defaults import VERTICAL_RECORDED
from rigkit.export.source import DepthMap

MAX_RESIDUAL_DEG = 1.5
"""A target whose line of sight misses its fitted ray by more than this stops the
export: a typing error, a swapped target, a magnetic disturbance."""
MIN_SPREAD_FRACTION = 0.25
MIN_SPREAD_DEG = 2.0
"""The targets' directions must span min(MIN_SPREAD_DEG, MIN_SPREAD_FRACTION x the
diagonal field of view): the roll about the optical axis rests on their spread."""
AZIMUTH_SIGMA_DEG = 1.0
INCLINATION_SIGMA_DEG = 0.25
"""One reading's direction error, one sigma, degrees: a compass rangefinder's (TruPulse
360: +-1 degree in azimuth, +-0.25 degree in inclination). The orientation's covariance
is propagated from them; the residuals say whether the readings did better or worse."""
_AZIMUTH_FLOOR_DEG = 0.01
"""Added to a steep line of sight's azimuth error (which shrinks as cos(inclination)),
so that a reading straight up is not taken as exact."""


class NotOnMap(InputError):
    """The session's points cannot be placed on the map; ``reason`` says why in words
    that fit after "not on the map: " (``--frame auto`` falls back to the camera frame
    and says it)."""

    def __init__(self, where: str, reason: str) -> None:
        super().__init__(f"{where}: {reason}")
        self.reason = reason


@dataclass(frozen=True)
class Sighting:
    """One target's direction twice: ``camera`` (3,) unit vector in the camera frame
    from its pixel, ``enu`` (3,) unit vector in ENU from the laser, the mean of
    ``readings`` readings."""

    name: str
    camera: np.ndarray
    enu: np.ndarray
    readings: int = 1


def sightings(session: Session, source: DepthMap) -> list[Sighting]:
    """The targets whose readings carry both azimuth and inclination, each direction
    the mean of its readings' (azimuths corrected to true north by the rig profile),
    each pixel's ray through the run's lens."""
    spec = session.rig().rangefinder
    found = []
    for target in session.targets:
        shots = [(r.azimuth_deg, r.inclination_deg) for r in target.readings
                 if r.azimuth_deg is not None and r.inclination_deg is not None]
        if not shots:
            continue
        enu = sum(enu_direction(spec.true_azimuth_deg(a) if spec else a, i) for a, i in shots)
        ray = source.lens.rays(np.array([target.pixel], np.float64))[0]
        found.append(Sighting(target.name, _unit(ray), _unit(np.asarray(enu)), len(shots)))
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


def orientation_covariance(found: list[Sighting]) -> np.ndarray:
    """(3, 3) covariance, rad^2, of the fitted rotation's error as a small rotation
    vector about ENU's axes (east, north, up): R_fit = exp([d]x) R_true. Each target's
    line of sight b is off by its readings' error, in azimuth (sigma
    :data:`AZIMUTH_SIGMA_DEG` x cos(inclination)) and inclination
    (:data:`INCLINATION_SIGMA_DEG`), each over sqrt(readings): covariance C_i across b.
    Linearised, Wahba's least squares (every target weighted alike, as
    :func:`wahba_rotation` fits) gives d = J^-1 sum A_i^T e_i with A_i = [b_i]x^T and
    J = sum A_i^T A_i, so cov(d) = J^-1 (sum A_i^T C_i A_i) J^-1 (the pixels' rays taken
    as exact)."""
    fit = np.zeros((3, 3))
    spread = np.zeros((3, 3))
    for sight in found:
        east, north, _ = sight.enu
        azimuth = math.atan2(east, north)
        along_azimuth = np.array([math.cos(azimuth), -math.sin(azimuth), 0.0])
        along_inclination = np.cross(sight.enu, along_azimuth)
        var_azimuth = (math.radians(AZIMUTH_SIGMA_DEG) * math.hypot(east, north)) ** 2 + (
            math.radians(_AZIMUTH_FLOOR_DEG) ** 2)
        error = (var_azimuth * np.outer(along_azimuth, along_azimuth)
                 + math.radians(INCLINATION_SIGMA_DEG) ** 2
                 * np.outer(along_inclination, along_inclination)) / sight.readings
        a = _skew(sight.enu).T
        fit += a.T @ a
        spread += a.T @ error @ a
    inverse = np.linalg.inv(fit)
    return inverse @ spread @ inverse


def _skew(v: np.ndarray) -> np.ndarray:
    """[v]x: the matrix with [v]x w = v x w."""
    return np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])


def _angle_deg(a: np.ndarray, b: np.ndarray) -> float:
    """Angle between unit vectors, degrees (atan2: accurate for small angles too)."""
    return math.degrees(math.atan2(np.linalg.norm(np.cross(a, b)), float(a @ b)))


def _spread_deg(vectors: list[np.ndarray]) -> float:
    return max(_angle_deg(a, b) for i, a in enumerate(vectors) for b in vectors[i + 1:])


@dataclass(frozen=True)
class Orientation:
    """The left camera's orientation: ``rotation`` (3, 3) maps camera-frame vectors to
    ENU; ``residuals_deg`` per target (``names``), degrees; ``spread_deg`` the widest
    angle between two targets' directions; ``covariance`` (3, 3), rad^2, of its error
    as a small rotation about east, north and up (:func:`orientation_covariance`)."""

    rotation: np.ndarray
    names: tuple[str, ...]
    residuals_deg: tuple[float, ...]
    spread_deg: float
    covariance: np.ndarray

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

    def pointing_sigma_deg(self) -> tuple[float, float, float]:
        """One sigma of :meth:`pointing`'s azimuth, elevation and roll, degrees, from the
        covariance: each angle's change under a small rotation d is g . d, with g = -up +
        tan(elevation) x the horizontal unit vector along the view for the azimuth, the
        horizontal axis across the view for the elevation, the optical axis for the
        roll."""
        forward = self.rotation[:, 2]
        level = max(math.hypot(forward[0], forward[1]), 1e-9)
        along = np.array([forward[0], forward[1], 0.0]) / level
        azimuth = np.array([0.0, 0.0, -1.0]) + forward[2] / level * along
        across = np.array([forward[1], -forward[0], 0.0]) / level

        def sigma(gradient: np.ndarray) -> float:
            return math.degrees(math.sqrt(float(gradient @ self.covariance @ gradient)))

        return sigma(azimuth), sigma(across), sigma(forward)

    def sideways_sigma(self, ray: np.ndarray) -> float:
        """How far (one sigma, per metre of range) the orientation's error moves a point
        on the camera-frame ``ray`` (3,) across its line of sight, rad: the covariance's
        part perpendicular to the line of sight."""
        b = self.rotation @ _unit(np.asarray(ray, np.float64))
        across = np.eye(3) - np.outer(b, b)
        return math.sqrt(float(np.trace(across @ self.covariance @ across)))


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
    """Solve the left camera's orientation from the session's targets; :class:`NotOnMap`
    (one line naming the cause) when fewer than two targets have directions, they lie
    too close together in the image, the laser's directions do not spread as the
    targets' pixels do, or one misses by more than ``max_residual_deg``."""
    where = str(session.path)
    found = sightings(session, source)
    if len(found) < 2:
        half = "".join(f"; {note}" for note in half_sighted(session))
        raise NotOnMap(
            where, f"georeferencing needs 2 or more targets with a laser azimuth and "
            f"inclination, {len(found)} have them{half} (rigkit session add-target ... "
            "--azimuth DEG --inclination DEG), or export with --frame camera")
    width, height = source.size
    fov = 2 * math.degrees(math.atan(math.hypot(width, height) / 2 / source.lens.focal_px))
    needed = min(MIN_SPREAD_DEG, MIN_SPREAD_FRACTION * fov)
    pixels = _spread_deg([s.camera for s in found])
    lines = _spread_deg([s.enu for s in found])
    if pixels < needed:
        raise NotOnMap(
            where, f"the targets lie within {pixels:.2f} deg of each other in the image, "
            f"under the {needed:.2f} deg needed to fix the camera's roll; add a target near "
            "another corner of the image")
    if lines < needed:
        raise NotOnMap(
            where, f"the laser's directions span {lines:.2f} deg although the targets lie "
            f"{pixels:.2f} deg apart in the image: the readings do not say where the laser "
            "pointed (a rangefinder that sends a fixed azimuth and inclination, or one "
            "direction typed for every target); take each target's azimuth and "
            "inclination from the laser")
    camera, enu = np.array([s.camera for s in found]), np.array([s.enu for s in found])
    rotation = wahba_rotation(camera, enu)
    residuals = tuple(_angle_deg(rotation @ s.camera, s.enu) for s in found)
    worst = int(np.argmax(residuals))
    if residuals[worst] > max_residual_deg:
        raise NotOnMap(
            where, f"target {found[worst].name}'s laser direction misses its pixel by "
            f"{residuals[worst]:.2f} deg after the best fit (limit {max_residual_deg:g}"
            " deg): check its azimuth, inclination and pixel, and the rig's declination")
    return Orientation(rotation, tuple(s.name for s in found), residuals,
                       min(pixels, lines),
                       orientation_covariance(found))


@dataclass(frozen=True)
class Georeference:
    """Where the camera frame lies on the map: the tripod's ``position``, the camera's
    ``orientation`` and the ``map`` (CRS, heights, PROJ's transformation)."""

    position: TripodPosition
    orientation: Orientation
    map: MapCrs
    left_out: tuple[str, ...] = ()
    """Targets left out for half a direction (:func:`half_sighted`)."""

    @property
    def crs(self) -> Any:
        """The pyproj CRS the files carry (horizontal + vertical)."""
        return self.map.crs

    @cached_property
    def _to_geographic(self) -> Any:
        """ENU at the tripod -> WGS 84 longitude, latitude (degrees), height (m)."""
        import pyproj

        p = self.position
        return pyproj.Transformer.from_pipeline(
            "+proj=pipeline "
            f"+step +inv +proj=topocentric +ellps=WGS84 +lat_0={p.lat_deg!r} "
            f"+lon_0={p.lon_deg!r} +h_0={self.map.tripod_height_m!r} "
            "+step +inv +proj=cart +ellps=WGS84 "
            "+step +proj=unitconvert +xy_in=rad +xy_out=deg")

    def enu_to_map(self, enu: np.ndarray) -> np.ndarray:
        """(n, 3) ENU metres from the tripod -> (n, 3) easting, northing (the CRS's unit)
        and height (m unless the vertical CRS says otherwise)."""
        lon, lat, height = self._to_geographic.transform(enu[:, 0], enu[:, 1], enu[:, 2])
        east, north, z = self.map.transformer.transform(lon, lat, height)
        return np.column_stack([east, north, z if self.map.z_from_transform else height])

    def to_map(self, xyz: np.ndarray) -> np.ndarray:
        """(n, 3) camera-frame points, m -> (n, 3) map coordinates (a point Transform)."""
        return self.enu_to_map(xyz @ self.orientation.rotation.T)

    @cached_property
    def origin(self) -> tuple[float, float, float]:
        """The tripod on the map: easting, northing, height."""
        e, n, h = self.enu_to_map(np.zeros((1, 3)))[0]
        return float(e), float(n), float(h)


def georeference(source: DepthMap, max_residual_deg: float = MAX_RESIDUAL_DEG, *,
                 crs: str | None = None, vertical: str = VERTICAL_RECORDED
                 ) -> Georeference:
    """The georeference of a session's depth map on the map ``crs`` (None: the tripod's
    UTM zone) with heights ``vertical`` (:func:`rigkit.export.crs.map_crs`).
    :class:`NotOnMap` when the session has no tripod position or its orientation cannot
    be solved (:func:`orient_camera`); InputError when the map asked for cannot be made."""
    session = source.session
    if session is None:
        raise NotOnMap(source.name, "a depth map file has no tripod position; export the "
                       "session to georeference it")
    position = session.tripod
    if position is None:
        raise NotOnMap(str(session.path), "no tripod position (rigkit session set-position)")
    on_map = map_crs(position, crs, vertical)
    orientation = orient_camera(session, source, max_residual_deg)
    return Georeference(position, orientation, on_map, tuple(half_sighted(session)))
