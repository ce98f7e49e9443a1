"""Pinhole camera geometry shared by the generator, the pipeline and the evaluation.

Conventions (OpenCV): camera x right, y down, z forward; pixel (u, v) with u along
columns, v along rows, pixel centres at integer coordinates. The world frame is the
**left camera's frame**. A camera stores ``R`` (world -> camera rotation) and its
centre ``C`` in world coordinates, so ``X_cam = R @ (X_world - C)``.
"""

from __future__ import annotations

from dataclasses import dataclass

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


@dataclass(frozen=True)
class Camera:
    """A pinhole camera: intrinsics ``K`` (3x3, px), rotation ``R`` (world->camera),
    centre ``C`` (3,) in metres (world = left camera frame), image ``width`` x ``height``."""

    K: F64
    R: F64
    C: F64
    width: int
    height: int

    @property
    def f(self) -> float:
        return float(self.K[0, 0])

    def project(self, X: NDArray[np.floating]) -> tuple[F64, F64]:
        """Project world points (..., 3) -> (pixels (..., 2), depth z in this camera (...))."""
        Xc = (np.asarray(X, dtype=np.float64) - self.C) @ self.R.T
        z = Xc[..., 2]
        uv = Xc[..., :2] / z[..., None] * self.f + self.K[:2, 2]
        return uv, z

    def rays(self, u: F64, v: F64) -> F64:
        """World-frame ray directions (..., 3), unnormalised, with unit z in the camera frame."""
        d_cam = np.stack(
            [(u - self.K[0, 2]) / self.f, (v - self.K[1, 2]) / self.f, np.ones_like(u)], axis=-1
        )
        return d_cam @ self.R  # R^T applied to row vectors
