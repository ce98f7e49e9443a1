"""LAS 1.4 and LAZ point clouds through laspy (LAZ compressed by the lazrs backend).

Point format 7: X, Y, Z as 32-bit integers times a scale plus an offset (chosen so the
whole map fits at millimetre steps where it can), intensity and red, green, blue from
the left image's grey value (x 257, so 255 is 65535), and an extra-bytes dimension
``sigma`` (float32, metres: the depth's one standard error). A point whose depth the
pipeline filled from a neighbour rather than matched has its synthetic bit set (the
classification flag readers filter on: PDAL's ``Synthetic``, LAStools' ``-drop_synthetic``).
A georeferenced file carries its CRS (horizontal and vertical, a compound CRS) in a WKT
VLR, as OGC 01-009 WKT (WKT1), which the LAS 1.4 specification (R15) cites, with the
global encoding's WKT bit set; QGIS, PDAL and CloudCompare read it and place the cloud
without asking.
"""

from __future__ import annotations

import math
from pathlib import Path
from types import TracebackType

import laspy
import numpy as np

from rigkit import __version__
from rigkit.errors import InputError
from rigkit.export.points import PointChunk

POINT_FORMAT = 7
SCALES_M = (0.001, 0.01, 0.1, 1.0)
_INT32 = 2**31 - 1


def las_scale(extent_m: float) -> float:
    """The finest of :data:`SCALES_M` at which coordinates within ``extent_m`` metres of
    the offset fit LAS's 32-bit integers."""
    for scale in SCALES_M:
        if extent_m / scale < _INT32 * 0.99:
            return scale
    raise InputError(f"points {extent_m:g} m from the origin do not fit a LAS file "
                     "(a depth map of that reach is no estimate of rigkit's); export PLY")


def las_header(offset: tuple[float, float, float], extent_m: float, wkt: str | None,
               description: str) -> laspy.LasHeader:
    """A LAS 1.4 point format 7 header with the ``sigma`` extra dimension. ``offset``:
    a point near the data (the tripod, or the camera's origin), metres; ``extent_m``: how
    far from it the farthest point may be; ``wkt``: the CRS as WKT1, or None (a local
    frame)."""
    header = laspy.LasHeader(point_format=POINT_FORMAT, version="1.4")
    header.add_extra_dim(laspy.ExtraBytesParams(
        name="sigma", type=np.float32, description="1-sigma depth error, m"))
    # laspy 2.7 takes a written extra dimension's min and max from each chunk's first
    # point only: leave the (optional) statistics out rather than wrong.
    for struct in header.vlrs.get("ExtraBytesVlr")[0].extra_bytes_structs:
        struct.options &= ~(struct.MIN_BIT_MASK | struct.MAX_BIT_MASK)
    header.offsets = np.array([math.floor(v) for v in offset], np.float64)
    header.scales = np.full(3, las_scale(extent_m))
    header.system_identifier = description[:32]
    header.generating_software = f"rigkit {__version__}"[:32]
    if wkt is not None:  # laspy's add_crs writes WKT2; LAS 1.4 cites WKT1
        header.vlrs.append(laspy.vlrs.known.WktCoordinateSystemVlr(wkt))
        header.global_encoding.wkt = True
    return header


class LasWriter:
    """Streams points to a LAS (``compress=False``) or LAZ file at ``path``."""

    def __init__(self, path: Path, header: laspy.LasHeader, *, compress: bool) -> None:
        self._header = header
        backend = laspy.LazBackend.Lazrs if compress else None
        self._writer = laspy.open(path, mode="w", header=header, do_compress=compress,
                                  laz_backend=backend)

    def write(self, chunk: PointChunk) -> None:
        points = laspy.ScaleAwarePointRecord.zeros(len(chunk.grey), header=self._header)
        points.x, points.y, points.z = chunk.xyz[:, 0], chunk.xyz[:, 1], chunk.xyz[:, 2]
        level = chunk.grey.astype(np.uint16) * 257
        points.intensity = level
        points.red = points.green = points.blue = level
        points.sigma = chunk.sigma
        one = np.ones(len(chunk.grey), np.uint8)  # one return per pixel: LAS 1.4 wants >= 1
        points.return_number = one
        points.number_of_returns = one
        if chunk.filled is not None:
            points.synthetic = chunk.filled
        self._writer.write_points(points)

    def close(self) -> None:
        self._writer.close()

    def __enter__(self) -> LasWriter:
        return self

    def __exit__(self, kind: type[BaseException] | None, error: BaseException | None,
                 trace: TracebackType | None) -> None:
        self.close()
