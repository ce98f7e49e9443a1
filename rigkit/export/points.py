"""A depth map as points, in chunks of rows so that memory stays bounded.

Camera frame (the left camera's, OpenCV's): x right, y down, z forward along the optical
axis, metres, origin at the optical centre. Pixel (u, v): u along columns, v along rows,
pixel centres at integers. A pixel at depth z lies at z times its ray, back-projected
through the run's lens (:meth:`rigkit.pipeline.lens.Lens.rays`: the recorded pixel
undistorted, then the ideal pinhole), as the laser comparison and the orientation fit
take it: the depth map lies on the recorded, distorted pixel grid.
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
    ``sigma``: (n,) float32, the depth's one standard error, metres; ``filled``: (n,)
    bool, the pipeline filled the point's depth from a neighbour (None: not known);
    ``ray_length``: (n,) float32, the length of the point's ray per metre of depth
    (>= 1: a depth error d moves the point d x ray_length along its line of sight);
    ``keep``: (h, w) bool, which of the chunk's grid points (its every ``step``-th row
    and column) these are; ``done``: the fraction of the map's rows covered so far."""

    xyz: np.ndarray
    grey: np.ndarray
    sigma: np.ndarray
    filled: np.ndarray | None
    ray_length: np.ndarray
    keep: np.ndarray
    done: float


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
    cols = slice(None, None, step)
    for rows in row_blocks((height, width), step):
        z = np.asarray(source.depth[rows, cols], np.float64)
        keep = estimated(z)
        x, y = source.lens.ray_rows(rows.start, rows.stop)
        shape = (rows.stop - rows.start, width)
        x = np.broadcast_to(x, shape)[::step, cols][keep]
        y = np.broadcast_to(y, shape)[::step, cols][keep]
        depth = z[keep]
        xyz = np.column_stack([x * depth, y * depth, depth])
        filled = source.filled(rows, cols)
        yield PointChunk(
            xyz=transform(xyz) if transform is not None else xyz,
            grey=np.asarray(source.grey[rows, cols])[keep],
            sigma=np.asarray(source.sigma[rows, cols], np.float32)[keep],
            filled=None if filled is None else filled[keep],
            ray_length=np.sqrt(x * x + y * y + 1.0).astype(np.float32),
            keep=keep,
            done=rows.stop / height,
        )
