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

from rigkit.core.threads import ViewPool
from rigkit.pipeline.lens import Lens
from rigkit.pipeline.rectify import Rectification, scaling

CHUNK_ROWS = 128
"""Rows of the left image per chunk of :func:`left_grid` (a multiple of
``rigkit.pipeline.lens.GRID_STEP``, so that the chunks' lens maps are the whole image's):
its float64 arrays (4.7 MB each at 4608 columns) stay in the cache; at 512 rows
:func:`to_left` took 0.87 s of CPU at 16 MP, at 128 rows 0.42 s."""


def rectified_rays(rect: Rectification, u: np.ndarray, disparity: np.ndarray) -> tuple:
    """Normalised x of the left and right rays (rectified frame, z = 1) for rectified
    left column ``u`` (px, full-resolution canvas) and rectified disparity (px),
    broadcast together: two float64 arrays, each computed in place."""
    f = rect.K[0, 0]
    cx = rect.K[0, 2] + rect.canvas[0, 2]
    a = np.subtract(u, cx, dtype=np.float64)
    a /= f
    b = np.subtract(u, disparity, dtype=np.float64)
    b -= rect.shift
    b -= cx
    b /= f
    return a, b


def triangulate_z(
    rect: Rectification, u: np.ndarray, disparity: np.ndarray, beta: float, baseline_m: float
) -> np.ndarray:
    """Depth (m, z in the left and rectified frames, which share the z axis) of rectified
    left column ``u`` with rectified ``disparity`` (broadcast together), for a
    right-camera yaw correction ``beta`` (rad). Non-positive or infinite results (behind
    the rig) become NaN. Float64, of the broadcast shape.

    ``a - (b + t) / (1 - b t)`` with :func:`rectified_rays`' ``a`` and ``b``, each step
    in place: on a chunk of a 16 MP image every fresh array of its size is memory
    traffic, which costs more than the arithmetic."""
    a, b = rectified_rays(rect, u, disparity)
    t = np.tan(beta)
    z = np.multiply(b, t)
    np.subtract(1.0, z, out=z)  # 1 - b t
    b += t
    np.divide(b, z, out=z)  # the right ray turned by beta: tan(atan(b) + beta)
    np.subtract(a, z, out=z)
    with np.errstate(divide="ignore", invalid="ignore"):
        np.divide(baseline_m, z, out=z)
        np.copyto(z, np.nan, where=~(z > 0))
    return z


def left_grid(
    rect: Rectification, scale: float, shape: tuple[int, int], lens: Lens | None
) -> Iterator[tuple]:
    """For row chunks of the original (recorded) left image: (rows, xs, ys, uf) where
    (xs, ys) are the pixels' positions on the ``scale``-resized rectified canvas
    (float32, for cv2.remap) and ``uf`` their full-resolution rectified column
    (float64). ``lens`` maps recorded to ideal pixels first (None: pinhole)."""
    for r0 in range(0, shape[0], CHUNK_ROWS):
        yield _grid_rows(rect, scale, shape, lens, r0)


def _grid_rows(
    rect: Rectification, scale: float, shape: tuple[int, int], lens: Lens | None, r0: int
) -> tuple:
    """:func:`left_grid`'s chunk of the rows from ``r0``."""
    H, W = shape
    h = rect.H_left
    S = scaling(scale)  # diagonal scale and shift: resized = S @ full resolution
    lens = lens or Lens(float(rect.K[0, 0]), (W, H))
    u, v = lens.ideal_rows(r0, min(r0 + CHUNK_ROWS, H))
    # In place where it can be: each fresh array of the chunk's size costs memory traffic.
    inv = np.add(h[2, 0] * u, h[2, 1] * v + h[2, 2])
    np.divide(1.0, inv, out=inv)  # homogeneous weight
    uf = np.add(h[0, 0] * u, h[0, 1] * v + h[0, 2])
    uf *= inv
    vf = np.add(h[1, 0] * u, h[1, 1] * v + h[1, 2])
    vf *= inv
    xs, ys = np.empty(uf.shape, np.float32), np.empty(uf.shape, np.float32)
    np.add(np.multiply(uf, S[0, 0], out=inv), S[0, 2], out=xs)  # rounded once to float32
    np.add(np.multiply(vf, S[1, 1], out=vf), S[1, 2], out=ys)
    return slice(r0, r0 + uf.shape[0]), xs, ys, uf


def to_left(
    disparity: np.ndarray,
    masks: tuple[np.ndarray, ...],
    scale: float,
    rect: Rectification,
    beta: float,
    baseline_m: float,
    shape: tuple[int, int],
    lens: Lens | None = None,
) -> tuple[np.ndarray, tuple[np.ndarray, ...]]:
    """Depth of every pixel of the original (recorded) left image, and masks of the
    rectified canvas carried to the same pixels, in one pass over :func:`left_grid`
    (each chunk of the grid is used once and its memory reused for the next), its
    chunks spread over a :class:`rigkit.core.threads.ViewPool`.

    disparity: (h, w) float32, px of the ``scale``-resized rectified canvas,
    ``x_left - x_right``, NaN = unknown. masks: up to 8 (h, w) bool on the same canvas.
    shape: (H, W) of the original left image.
    Returns depth: (H, W) float32, metres, z in the left camera frame, NaN where
    unknown; and the masks: each (H, W) bool, nearest neighbour, False outside the canvas.
    """
    depth = np.empty(shape, np.float32)
    # The masks travel as the bits of one 8-bit channel: OpenCV remaps one channel
    # fastest (three channels cost 0.13-0.24 s more at 16 MP).
    packed = np.zeros(disparity.shape, np.uint8)
    out = tuple(np.empty(shape, bool) for _ in masks)

    def pack(r0: int) -> None:
        rows = slice(r0, r0 + CHUNK_ROWS)
        for k, mask in enumerate(masks):
            packed[rows] |= mask[rows].astype(np.uint8) << k

    def chunk(r0: int) -> None:
        rows, xs, ys, uf = _grid_rows(rect, scale, shape, lens, r0)
        d = cv2.remap(disparity, xs, ys, cv2.INTER_LINEAR, borderValue=np.nan)
        depth[rows] = triangulate_z(rect, uf, d / scale, beta, baseline_m)
        bits = cv2.remap(packed, xs, ys, cv2.INTER_NEAREST, borderValue=0)
        for k, mask in enumerate(out):
            np.not_equal(np.bitwise_and(bits, np.uint8(1 << k)), 0, out=mask[rows])

    # Each chunk's rows are its own: spread over threads, they come out as in turn.
    with ViewPool() as pool:
        pool.map(pack, range(0, disparity.shape[0], CHUNK_ROWS))
        pool.map(chunk, range(0, shape[0], CHUNK_ROWS))
    return depth, out
