"""A depth map as points, in chunks of rows so that memory stays bounded.

Camera frame (the left camera's, OpenCV's): x right, y down, z forward along the optical
axis, metres, origin at the optical centre. Pixel (u, v): u along columns, v along rows,
pixel centres at integers. A pixel at depth z lies at
((u - cx) / f * z, (v - cy) / f * z, z): the pinhole model the laser comparison uses
(:mod:`rigkit.rangefinder.ranging`; the lens distortion, 0.2 % at the corner of the
bundled example, moves a point sideways by that share of its distance from the axis).
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from dataclasses import dataclass

import numpy as np

from rigkit.export.source import DepthMap

CHUNK_POINTS = 1 << 19
"""Grid points per chunk: under 100 MB of temporaries at a time, whatever the map's size
(measured: 4608 x 3456 to PLY, LAS, LAZ and TIFF on the map peaks at 350 MB resident,
of which 145 MB are the memory-mapped depth, sigma and grey)."""

Transform = Callable[[np.ndarray], np.ndarray]
"""Camera-frame points (n, 3) float64 m -> output coordinates (n, 3) float64."""


@dataclass(frozen=True)
class PointChunk:
    """Consecutive points of the map in row-major order. ``xyz``: (n, 3) float64, the
    output frame's coordinates (metres); ``grey``: (n,) uint8, the left image's value;
    ``sigma``: (n,) float32, the depth's one standard error, metres; ``done``: the
    fraction of the map's rows covered so far."""

    xyz: np.ndarray
    grey: np.ndarray
    sigma: np.ndarray
    done: float


def camera_rays(u: np.ndarray, v: np.ndarray, f: float, cx: float, cy: float) -> np.ndarray:
    """Rays of pixels (u, v) (equal shapes, px) with unit z: (..., 3) float64 in the
    camera frame; a point at depth z is ``z * ray``."""
    u, v = np.broadcast_arrays(np.asarray(u, np.float64), np.asarray(v, np.float64))
    return np.stack([(u - cx) / f, (v - cy) / f, np.ones_like(u)], axis=-1)


def row_blocks(shape: tuple[int, int], step: int) -> Iterator[slice]:
    """Slices of rows, every ``step``-th, of about :data:`CHUNK_POINTS` grid points each
    for a map of ``shape`` (H, W) subsampled by ``step`` in both directions."""
    height, width = shape
    per = max(1, CHUNK_POINTS // len(range(0, width, step)))
    for top in range(0, height, step * per):
        yield slice(top, min(top + step * per, height), step)


def count_points(depth: np.ndarray, step: int) -> int:
    """Points a map gives on the grid of every ``step``-th row and column: the finite,
    positive depths there."""
    return sum(int(estimated(depth[rows, ::step]).sum()) for rows in row_blocks(depth.shape, step))


def estimated(z: np.ndarray) -> np.ndarray:
    """Which depths (any shape, metres) are estimates: finite and positive."""
    with np.errstate(invalid="ignore"):
        return np.isfinite(z) & (z > 0)


def point_chunks(source: DepthMap, step: int, transform: Transform | None = None
                 ) -> Iterator[PointChunk]:
    """The map's points on every ``step``-th row and column, row by row, NaN skipped, in
    chunks of about :data:`CHUNK_POINTS` grid points; ``transform`` maps camera-frame
    points to the output frame (None: the camera frame)."""
    height, width = source.depth.shape
    cols = np.arange(0, width, step)
    for rows in row_blocks((height, width), step):
        z = np.asarray(source.depth[rows, ::step], np.float64)
        keep = estimated(z)
        vv, uu = np.meshgrid(np.arange(height)[rows], cols, indexing="ij")
        xyz = camera_rays(uu[keep], vv[keep], source.f, source.cx, source.cy) * z[keep, None]
        yield PointChunk(
            xyz=transform(xyz) if transform is not None else xyz,
            grey=np.asarray(source.grey[rows, ::step])[keep],
            sigma=np.asarray(source.sigma[rows, ::step], np.float32)[keep],
            done=rows.stop / height,
        )
