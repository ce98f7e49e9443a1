"""Stage 4: metric depth from rectified disparity, in the original left image's grid.

Instead of ``z = f C_lr / d`` on the rectified grid (exact only for an exactly
rectified pair), each left pixel is triangulated with the fitted geometry: its
rectified position and matched right position are turned back into rays through the
exact homographies, the right ray is turned by the yaw correction ``beta`` found by
ambiguity removal, and the two rays are intersected with the baseline ``C_lr``.
To first order this is the paper's ``z = f C_lr / (d + q)`` with ``q = f * beta``.
"""

from __future__ import annotations

from collections.abc import Iterator

import cv2
import numpy as np

from rigkit.pipeline.lens import Lens
from rigkit.pipeline.rectify import Rectification, scaling

CHUNK_ROWS = 512


def rectified_rays(rect: Rectification, u: np.ndarray, disparity: np.ndarray) -> tuple:
    """Normalised x of the left and right rays (rectified frame, z = 1) for rectified
    left column ``u`` (px, full-resolution canvas) and rectified disparity (px)."""
    f = rect.K[0, 0]
    cx = rect.K[0, 2] + rect.canvas[0, 2]
    a = (u - cx) / f
    b = (u - disparity - rect.shift - cx) / f
    return a, b


def triangulate_z(
    rect: Rectification, u: np.ndarray, disparity: np.ndarray, beta: float, baseline_m: float
) -> np.ndarray:
    """Depth (m, z in the left and rectified frames, which share the z axis) of rectified
    left column ``u`` with rectified ``disparity``, for a right-camera yaw correction
    ``beta`` (rad). Non-positive or infinite results (behind the rig) become NaN."""
    a, b = rectified_rays(rect, u, disparity)
    denom = a - np.tan(np.arctan(b) + beta)
    with np.errstate(divide="ignore", invalid="ignore"):
        z = baseline_m / denom
    return np.where(z > 0, z, np.nan)


def left_grid(
    rect: Rectification, scale: float, shape: tuple[int, int], lens: Lens | None
) -> Iterator[tuple]:
    """For row chunks of the original (recorded) left image: (rows, xs, ys, uf) where
    (xs, ys) are the pixels' positions on the ``scale``-resized rectified canvas
    (float32, for cv2.remap) and ``uf`` their full-resolution rectified column
    (float64). ``lens`` maps recorded to ideal pixels first (None: pinhole)."""
    H, W = shape
    M = scaling(scale) @ rect.H_left
    Hl = rect.H_left
    lens = lens or Lens(float(rect.K[0, 0]), (W, H))
    for r0 in range(0, H, CHUNK_ROWS):
        uu, vv = lens.ideal_rows(r0, min(r0 + CHUNK_ROWS, H))
        q = M[:, 0, None, None] * uu + M[:, 1, None, None] * vv + M[:, 2, None, None]
        xs, ys = (q[0] / q[2]).astype(np.float32), (q[1] / q[2]).astype(np.float32)
        uf = (Hl[0, 0] * uu + Hl[0, 1] * vv + Hl[0, 2]) / (Hl[2, 0] * uu + Hl[2, 1] * vv + Hl[2, 2])
        yield slice(r0, r0 + uu.shape[0]), xs, ys, uf


def depth_map(
    disparity: np.ndarray,
    disparity_scale: float,
    rect: Rectification,
    beta: float,
    baseline_m: float,
    shape: tuple[int, int],
    lens: Lens | None = None,
    grid: list[tuple] | None = None,
) -> np.ndarray:
    """Depth of every pixel of the original (recorded) left image (``grid``: the
    :func:`left_grid` of the same arguments, when already computed).

    disparity: (h, w) float32, px of the ``disparity_scale``-resized rectified canvas,
    ``x_left - x_right``, NaN = unknown. shape: (H, W) of the original left image.
    Returns (H, W) float32, metres, z in the left camera frame, NaN where unknown.
    """
    out = np.empty(shape, np.float32)
    for rows, xs, ys, uf in grid or left_grid(rect, disparity_scale, shape, lens):
        d = cv2.remap(disparity, xs, ys, cv2.INTER_LINEAR, borderValue=np.nan)
        out[rows] = triangulate_z(rect, uf, d / disparity_scale, beta, baseline_m)
    return out


def mask_to_left(
    mask: np.ndarray,
    scale: float,
    rect: Rectification,
    shape: tuple[int, int],
    lens: Lens | None = None,
    grid: list[tuple] | None = None,
) -> np.ndarray:
    """Resample bool masks of the ``scale``-resized rectified canvas to the original
    left grid (nearest neighbour), all in one pass: ``mask`` (h, w) or (h, w, c) with
    c <= 4. Returns (H, W) or (H, W, c) bool."""
    out = np.zeros(shape + mask.shape[2:], bool)
    src = mask.astype(np.uint8)
    for rows, xs, ys, _ in grid or left_grid(rect, scale, shape, lens):
        out[rows] = cv2.remap(src, xs, ys, cv2.INTER_NEAREST, borderValue=0) > 0
    return out
