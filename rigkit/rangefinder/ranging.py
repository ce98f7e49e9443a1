"""The one conversion between a laser range and a depth map's z, both ways.

A rangefinder measures the **range r along its line of sight**, from its aperture; a
depth map stores **z along the left camera's optical axis**. The functions here take
the laser spot's ray (:data:`Ray`: its pixel back-projected through the run's lens,
:meth:`rigkit.pipeline.lens.Lens.rays`, as the laser comparison and ``rigkit export`` do;
or an undistorted pixel and pinhole intrinsics) and the aperture's offset from the
camera's optical centre, and find the point on the ray that is at depth z / at range r
from the aperture.

Pixel convention (the one the pipeline, the depth maps and :mod:`rigkit.synth` use):
(u, v) with u along columns and v along rows, **pixel centres at integer
coordinates**, so the top-left pixel's centre is (0, 0) and the image centre of a
W x H image is ((W - 1) / 2, (H - 1) / 2). A rig profile's ``principal_point_px`` is
measured from the top-left pixel's *corner* (docs/rig-profiles.md);
:meth:`rigkit.rig.profile.RigProfile.intrinsics` turns a profile into (f, cx, cy) in the
convention here (it subtracts 0.5 px), for the pipeline and export alike.

The aperture offset is (right, up, forward) in metres, as a rig profile's
``rangefinder.offset`` gives it.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

from rigkit.errors import InputError
from rigkit.rangefinder.framing import FrameError, check_range, parse_decimal
from rigkit.rangefinder.protocols import PROTOCOLS

if TYPE_CHECKING:  # annotations only: the rig profile brings the pipeline with it
    from rigkit.rig.profile import RigProfile

MANUAL_MAX_RANGE_M = 5000.0
"""The longest range accepted when readings are typed in and the rig profile names no
``rangefinder.max_range_m``: beyond handheld lasers, far beyond rigkit's 200-500 m."""

Offset = tuple[float, float, float]
NO_OFFSET: Offset = (0.0, 0.0, 0.0)


def max_range_m(profile: RigProfile) -> float:
    """The longest laser range the rig's rangefinder can give, m: the profile's
    ``rangefinder.max_range_m``, else its protocol's, else :data:`MANUAL_MAX_RANGE_M`."""
    spec = profile.rangefinder
    if spec is not None and spec.max_range_m is not None:
        return spec.max_range_m
    if spec is not None and spec.protocol in PROTOCOLS:
        return PROTOCOLS[spec.protocol].max_range_m
    return MANUAL_MAX_RANGE_M


def parse_typed_range(text: str, profile: RigProfile) -> float:
    """A range typed in by hand (``"312.4"``), in metres: digits with optional decimals,
    positive and within :func:`max_range_m`; InputError naming the value otherwise (a
    typo such as ``3000000`` for ``300.0``, or ``1e300``, never becomes a reading)."""
    try:
        value = parse_decimal(text, "range")
        return check_range(value, max_range_m(profile), "range")
    except FrameError as exc:
        raise InputError(f"{exc} (type it in metres, e.g. 312.4)") from None


Ray = tuple[float, float, float]
"""A pixel's ray in the camera frame (x right, y down, z forward) with unit z: the point
at depth z on it is z times the ray. Through the run's lens:
:meth:`rigkit.pipeline.lens.Lens.rays`; a pinhole's: :func:`pinhole_ray`."""


def pinhole_ray(pixel: tuple[float, float], fx: float, fy: float, cx: float, cy: float
                ) -> Ray:
    """The :data:`Ray` of ``pixel`` (u, v) of an undistorted image with pinhole
    intrinsics ``fx``, ``fy``, ``cx``, ``cy`` (px, pixel centres at integers)."""
    return (pixel[0] - cx) / fx, (pixel[1] - cy) / fy, 1.0


def _aperture(offset_m: Offset) -> Ray:
    """The aperture's (right, up, forward) offset in the camera frame (y down)."""
    return offset_m[0], -offset_m[1], offset_m[2]


def depth_on_ray(range_m: float, ray: Ray, offset_m: Offset = NO_OFFSET) -> float:
    """Depth z in metres (along the optical axis) of the point on ``ray`` (a
    :data:`Ray`) at distance ``range_m`` from the laser's aperture, which sits
    ``offset_m`` (right, up, forward, m) from the camera's optical centre. With no offset
    this is ``range_m * cos(angle off axis)``: 0.14 % less than the range at 3 degrees.
    InputError if the range cannot reach the ray. Inverse of :func:`range_on_ray`."""
    norm = math.sqrt(sum(c * c for c in ray))
    direction = tuple(c / norm for c in ray)
    aperture = _aperture(offset_m)
    along = sum(d * o for d, o in zip(direction, aperture, strict=True))
    reach = along * along - sum(o * o for o in aperture) + range_m * range_m
    if range_m <= 0 or reach < 0:
        raise InputError(f"range {range_m} m cannot reach the ray from offset {offset_m} m")
    return (along + math.sqrt(reach)) * direction[2]


def range_on_ray(depth_m: float, ray: Ray, offset_m: Offset = NO_OFFSET) -> float:
    """Distance in metres from the laser's aperture to the point at depth ``depth_m`` on
    ``ray`` (conventions as :func:`depth_on_ray`, whose inverse it is)."""
    return math.dist(tuple(c * depth_m for c in ray), _aperture(offset_m))


def depth_from_range(
    range_m: float,
    pixel: tuple[float, float],
    *,
    fx: float,
    fy: float,
    cx: float,
    cy: float,
    offset_m: Offset = NO_OFFSET,
) -> float:
    """:func:`depth_on_ray` for ``pixel`` (u, v) of the undistorted image with pinhole
    intrinsics ``fx``, ``fy``, ``cx``, ``cy`` in pixels, pixel centres at integers (see
    the module). Inverse of :func:`range_from_depth`."""
    return depth_on_ray(range_m, pinhole_ray(pixel, fx, fy, cx, cy), offset_m)


def range_from_depth(
    depth_m: float,
    pixel: tuple[float, float],
    *,
    fx: float,
    fy: float,
    cx: float,
    cy: float,
    offset_m: Offset = NO_OFFSET,
) -> float:
    """:func:`range_on_ray` for ``pixel`` of the undistorted image (conventions as
    :func:`depth_from_range`, whose inverse it is)."""
    return range_on_ray(depth_m, pinhole_ray(pixel, fx, fy, cx, cy), offset_m)


def aperture_offset(profile: RigProfile) -> Offset:
    """The rangefinder aperture's (right, up, forward) offset in metres; zero if the
    profile gives none."""
    spec = profile.rangefinder
    if spec is None or spec.offset_m is None:
        return NO_OFFSET
    return spec.offset_m
