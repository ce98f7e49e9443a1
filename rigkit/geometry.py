"""Pinhole camera geometry shared by the generator, the pipeline and the evaluation.

Conventions (OpenCV): camera x right, y down, z forward; pixel (u, v) with u along
columns, v along rows, pixel centres at integer coordinates. The world frame is the
**left camera's frame**. A camera stores ``R`` (world -> camera rotation) and its
centre ``C`` in world coordinates, so ``X_cam = R @ (X_world - C)``.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

F64 = NDArray[np.float64]


def rot_x(a: float) -> F64:
    c, s = np.cos(a), np.sin(a)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def rot_y(a: float) -> F64:
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def rot_z(a: float) -> F64:
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def euler_to_matrix(x_deg: float, y_deg: float, z_deg: float) -> F64:
    """R = Rz(z) @ Ry(y) @ Rx(x), angles in degrees (the paper's Prop. 1 convention)."""
    return rot_z(np.radians(z_deg)) @ rot_y(np.radians(y_deg)) @ rot_x(np.radians(x_deg))


def rotvec_to_matrix(w: NDArray[np.floating]) -> F64:
    """Rodrigues: rotation vector (rad, axis * angle) -> 3x3 matrix."""
    w = np.asarray(w, dtype=np.float64)
    theta = float(np.linalg.norm(w))
    if theta < 1e-15:
        return np.eye(3)
    k = w / theta
    kx = np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
    return np.eye(3) + np.sin(theta) * kx + (1.0 - np.cos(theta)) * (kx @ kx)


def intrinsics(f_px: float, cx: float, cy: float) -> F64:
    """3x3 pinhole matrix with square pixels and no skew."""
    return np.array([[f_px, 0.0, cx], [0.0, f_px, cy], [0.0, 0.0, 1.0]])


def focal_from_fov(width_px: int, hfov_deg: float) -> float:
    """Focal length in px for a horizontal field of view over ``width_px`` pixels."""
    return float(width_px / 2.0 / np.tan(np.radians(hfov_deg) / 2.0))


Distortion = tuple[float, float, float, float, float]
NO_DISTORTION: Distortion = (0.0, 0.0, 0.0, 0.0, 0.0)


def distortion_coefficients(values: tuple[float, ...] | list[float]) -> Distortion:
    """OpenCV's ``k1, k2, p1, p2, k3`` from 1, 2, 4 or 5 numbers (missing ones are 0)."""
    if len(values) not in (1, 2, 4, 5):
        raise ValueError(f"distortion takes 1, 2, 4 or 5 coefficients (k1,k2,p1,p2,k3), got "
                         f"{len(values)}")
    full = [float(v) for v in values] + [0.0] * (5 - len(values))
    if not all(np.isfinite(full)):
        raise ValueError(f"distortion coefficients must be finite numbers, got {values}")
    return (full[0], full[1], full[2], full[3], full[4])


def distort(x: F64, y: F64, d: Distortion) -> tuple[F64, F64]:
    """OpenCV's radial-tangential model (Brown-Conrady): ideal normalised image
    coordinates ``(x, y)`` (z = 1, any shape) -> distorted normalised coordinates.
    Terms whose coefficients are zero are left out (:func:`_radial`): the same numbers
    (but the sign of a zero), with fewer passes over the points; the lens fit calls
    this some 4000 times with one radial term."""
    k1, k2, p1, p2, k3 = d
    r2 = x * x + y * y
    radial = _radial(r2, k1, k2, k3)
    if p1 == 0.0 and p2 == 0.0:
        return x * radial, y * radial
    xd = x * radial + 2.0 * p1 * x * y + p2 * (r2 + 2.0 * x * x)
    yd = y * radial + p1 * (r2 + 2.0 * y * y) + 2.0 * p2 * x * y
    return xd, yd


def _radial(r2: F64, k1: float, k2: float, k3: float) -> F64:
    """``1 + k1 r^2 + k2 r^4 + k3 r^6`` of ``r2`` = r^2, by Horner's rule; where ``k2``
    and ``k3`` are zero, ``1 + k1 r^2``, which is the same number (adding a zero product
    to ``k1`` leaves it as it is)."""
    if k2 == 0.0 and k3 == 0.0:
        return 1.0 + r2 * k1
    return 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3))


def undistort(xd: F64, yd: F64, d: Distortion, iterations: int = 8) -> tuple[F64, F64]:
    """Inverse of :func:`distort` by fixed-point iteration (as OpenCV's
    ``undistortPoints``). At a few-percent distortion each iteration gains two orders of
    magnitude, so 8 are far below 1e-9 in normalised units for telephoto fields. Zero
    terms are left out as in :func:`distort`."""
    if d == NO_DISTORTION:
        return xd, yd
    k1, k2, p1, p2, k3 = d
    tangential = p1 != 0.0 or p2 != 0.0
    x, y = xd, yd
    for _ in range(iterations):
        r2 = x * x + y * y
        radial = _radial(r2, k1, k2, k3)
        if not tangential:
            x, y = xd / radial, yd / radial
            continue
        x = (xd - 2.0 * p1 * x * y - p2 * (r2 + 2.0 * x * x)) / radial
        y = (yd - p1 * (r2 + 2.0 * y * y) - 2.0 * p2 * x * y) / radial
    return x, y


@dataclass(frozen=True)
class Camera:
    """A camera: intrinsics ``K`` (3x3, px), rotation ``R`` (world->camera), centre ``C``
    (3,) in metres (world = left camera frame), image ``width`` x ``height``, and lens
    ``distortion`` (OpenCV ``k1, k2, p1, p2, k3`` on normalised coordinates; zeros =
    pinhole)."""

    K: F64
    R: F64
    C: F64
    width: int
    height: int
    distortion: Distortion = field(default=NO_DISTORTION)

    @property
    def f(self) -> float:
        return float(self.K[0, 0])

    def project(self, X: NDArray[np.floating]) -> tuple[F64, F64]:
        """Project world points (..., 3) -> (pixels (..., 2), depth z in this camera (...))."""
        Xc = (np.asarray(X, dtype=np.float64) - self.C) @ self.R.T
        z = Xc[..., 2]
        x, y = distort(Xc[..., 0] / z, Xc[..., 1] / z, self.distortion)
        uv = np.stack([x, y], axis=-1) * self.f + self.K[:2, 2]
        return uv, z

    def rays(self, u: F64, v: F64) -> F64:
        """World-frame ray directions (..., 3), unnormalised, with unit z in the camera
        frame, through pixels ``(u, v)`` of the (distorted) image."""
        x, y = undistort((u - self.K[0, 2]) / self.f, (v - self.K[1, 2]) / self.f, self.distortion)
        d_cam = np.stack([x, y, np.ones_like(x)], axis=-1)
        return d_cam @ self.R  # R^T applied to row vectors
