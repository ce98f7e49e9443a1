"""PLY point clouds (binary little endian), written with NumPy in chunks.

The format is Greg Turk's (Stanford, 1994): an ASCII header naming the element ``vertex``,
its count and its properties, then the vertices as packed binary records. rigkit writes

    x, y, z          float (camera frame) or double (map coordinates: a UTM easting needs
                     more than float's 7 digits), metres
    red, green, blue uchar, the left image's grey value (so viewers colour the points)
    sigma            float, the depth's one standard error, metres (a scalar field in
                     CloudCompare)
    filled           uchar, 1 where the pipeline filled the depth from a neighbour rather
                     than matched it, else 0 (left out where the results do not say)

and says in ``comment`` lines which frame or CRS the coordinates are in. MeshLab,
CloudCompare, Open3D and Blender read it.
"""

from __future__ import annotations

from types import TracebackType
from typing import BinaryIO

import numpy as np

from rigkit.export.points import PointChunk


def vertex_dtype(double: bool, filled: bool = True) -> np.dtype:
    """One vertex record: coordinates float64 (``double``) or float32, grey as RGB,
    sigma, and (``filled``) whether the depth was filled."""
    coordinate = "<f8" if double else "<f4"
    return np.dtype([("x", coordinate), ("y", coordinate), ("z", coordinate),
                     ("red", "u1"), ("green", "u1"), ("blue", "u1"), ("sigma", "<f4"),
                     *([("filled", "u1")] if filled else [])])


_PLY_TYPES = {"<f8": "double", "<f4": "float", "|u1": "uchar"}


def ply_header(count: int, dtype: np.dtype, comments: list[str]) -> bytes:
    """The header for ``count`` vertices of ``dtype`` (from :func:`vertex_dtype`)."""
    lines = ["ply", "format binary_little_endian 1.0"]
    lines += [f"comment {c}" for c in comments]
    lines.append(f"element vertex {count}")
    lines += [f"property {_PLY_TYPES[dtype[name].str]} {name}" for name in dtype.names or ()]
    lines.append("end_header")
    return ("\n".join(lines) + "\n").encode("ascii")


class PlyWriter:
    """Streams ``count`` vertices to ``handle`` (opened for binary writing); the count
    must be known first (PLY's header holds it), and :meth:`close` checks it was met."""

    def __init__(self, handle: BinaryIO, count: int, *, double: bool, comments: list[str],
                 filled: bool = True):
        self._handle = handle
        self._dtype = vertex_dtype(double, filled)
        self._left = count
        handle.write(ply_header(count, self._dtype, comments))

    def write(self, chunk: PointChunk) -> None:
        records = np.empty(len(chunk.grey), self._dtype)
        for axis, name in enumerate("xyz"):
            records[name] = chunk.xyz[:, axis]
        for name in ("red", "green", "blue"):
            records[name] = chunk.grey
        records["sigma"] = chunk.sigma
        if "filled" in (self._dtype.names or ()):
            records["filled"] = chunk.filled
        self._handle.write(records.tobytes())
        self._left -= len(records)

    def close(self) -> None:
        self._handle.close()
        if self._left != 0:
            raise RuntimeError(f"PLY header announced {self._left} more vertices than written")

    def __enter__(self) -> PlyWriter:
        return self

    def __exit__(self, kind: type[BaseException] | None, error: BaseException | None,
                 trace: TracebackType | None) -> None:
        if error is None:
            self.close()
        else:
            self._handle.close()
