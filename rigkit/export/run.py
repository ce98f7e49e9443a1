"""One export: a depth map to point clouds (PLY, LAS, LAZ), a raster in the image's grid
(TIFF) and a map raster (DSM, a Cloud-Optimized GeoTIFF), in the left camera's frame or,
for a session that knows where its tripod stood, on the map; with a metadata file
(``NAME.export.json``, :mod:`rigkit.export.sidecar`) beside them.

The map is read in chunks of rows (:func:`rigkit.export.points.point_chunks`), and every
point format is written from the same chunks, which also gather the DSM's extent and
spacing; the DSM grids the points in a second pass (:mod:`rigkit.export.dsm`). All files
are staged in a hidden folder inside the output folder and renamed into place together at
the end (:func:`rigkit.core.outputs.staged_outputs`), so a failure leaves no partial output,
and never over a file rigkit did not write nor inside a session's own parts.

``--frame auto`` places the points on the map when the session has a tripod position and
falls back to the camera frame, saying why in one line, when its orientation cannot be
solved (:class:`rigkit.export.georef.NotOnMap`); what only a map can give (a DSM, a CRS or
heights asked for) is refused instead.
"""

from __future__ import annotations

import contextlib
import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from rigkit.capture.session import utc_now
from rigkit.core.files import check_writable_folder
from rigkit.core.outputs import check_output_folder, check_outputs, staged_outputs
from rigkit.core.signals import terminate_as_interrupt
from rigkit.errors import InputError
from rigkit.export.defaults import VERTICAL_RECORDED
from rigkit.export.dsm import NODATA, Footprint, Gridder, write_dsm
from rigkit.export.georef import MAX_RESIDUAL_DEG, Georeference, NotOnMap, georeference
from rigkit.export.las import LasWriter, las_header
from rigkit.export.ply import PlyWriter
from rigkit.export.points import count_points, estimated, point_chunks, row_blocks
from rigkit.export.sidecar import SIDECAR_SUFFIX, dumps, sidecar
from rigkit.export.source import DepthMap, open_depth
from rigkit.export.tiff import write_tiff

FORMATS = ("ply", "las", "laz", "tif", "dsm")
CLOUDS = ("ply", "las", "laz")
DEFAULT_FORMATS = ("ply", "las")
FRAMES = ("auto", "camera", "map")
CAMERA_FRAME = "left camera: x right, y down, z forward, metres"
EXPORT_DIR = "export"
"""Where the field TUI exports a session: ``SESSION/export/``."""

Report = Callable[[str, float], None]


@dataclass(frozen=True)
class MapRequest:
    """What the map is to be: ``crs`` (None: the tripod's UTM zone), ``vertical``
    (:mod:`rigkit.export.crs`), ``cell`` of the DSM (CRS units; None: from the points'
    spacing)."""

    crs: str | None = None
    vertical: str = VERTICAL_RECORDED
    cell: float | None = None

    def asked(self) -> list[str]:
        """The options that only a map can honour, as the user gave them."""
        return [option for option, given in (("--crs", self.crs is not None),
                                             ("--vertical", self.vertical != VERTICAL_RECORDED),
                                             ("--cell", self.cell is not None)) if given]


@dataclass(frozen=True)
class Exported:
    """What an export wrote: ``files`` (the metadata file last); ``points`` per point
    cloud, ``filled`` of them (None: not known); ``median_z_m``, the median depth of the
    exported grid; ``frame`` in words; ``georef`` when on the map; ``note``: why not on
    the map, where ``--frame auto`` fell back to the camera frame; ``dsm``: the DSM's
    grid (cell, size, how the cell was chosen) when one was written."""

    files: tuple[Path, ...]
    points: int
    median_z_m: float
    frame: str
    georef: Georeference | None
    seconds: float
    note: str | None = None
    filled: int | None = None
    dsm: dict[str, Any] | None = None


def parse_formats(text: str) -> tuple[str, ...]:
    """``ply,las`` -> ("ply", "las"); InputError naming an unknown format."""
    formats = tuple(dict.fromkeys(f.strip().lower() for f in text.split(",") if f.strip()))
    unknown = [f for f in formats if f not in FORMATS]
    if unknown or not formats:
        raise InputError(f"--format {text!r}: choose from {', '.join(FORMATS)}")
    return formats


def export_path(path: Path, out: Path, formats: Sequence[str] = DEFAULT_FORMATS, *,
                step: int = 1, frame: str = "auto", max_residual_deg: float = MAX_RESIDUAL_DEG,
                request: MapRequest | None = None, progress: Report | None = None
                ) -> Exported:
    """Export the session or depth map file at ``path`` into the folder ``out`` (see
    :func:`export_depth`). ``frame``: ``camera``, ``map`` (georeferenced; InputError if
    it cannot be), or ``auto``: on the map when the session has a tripod position and
    its orientation can be solved, else in the camera frame with a note saying why."""
    if frame not in FRAMES:
        raise InputError(f"frame {frame!r}: choose from {', '.join(FRAMES)}")
    request = request or MapRequest()
    source = open_depth(path)
    georef, note = _place(source, frame, max_residual_deg, request)
    needs_map = request.asked() + (["--format dsm"] if "dsm" in formats else [])
    if georef is None and needs_map:
        why = note or "--frame camera"
        verb = "needs" if len(needs_map) == 1 else "need"
        raise InputError(f"{' and '.join(needs_map)} {verb} the map, and {source.name} is not "
                         f"on it: {why}")
    return export_depth(source, out, formats, step=step, georef=georef, note=note,
                        cell=request.cell, progress=progress)


def _place(source: DepthMap, frame: str, max_residual_deg: float, request: MapRequest
           ) -> tuple[Georeference | None, str | None]:
    """The georeference ``frame`` asks for, or None and why not (``auto``)."""
    if frame == "camera":
        return None, None
    session = source.session
    if frame == "auto" and (session is None or session.tripod is None):
        return None, ("a depth map file has no tripod position" if session is None
                      else "the session has no tripod position (rigkit session set-position)")
    try:
        return georeference(source, max_residual_deg, crs=request.crs,
                            vertical=request.vertical), None
    except NotOnMap as exc:
        if frame == "map":
            raise
        return None, exc.reason


def export_depth(source: DepthMap, out: Path, formats: Sequence[str], *, step: int = 1,
                 georef: Georeference | None = None, note: str | None = None,
                 cell: float | None = None, progress: Report | None = None) -> Exported:
    """Write ``source`` as ``<name>.<format>`` for each of ``formats`` into ``out`` (the
    DSM as ``<name>.dsm.tif``), and ``<name>.export.json``: a point per estimated pixel
    on every ``step``-th row and column, in the camera frame or, with ``georef``, on its
    map; ``note``: why not on the map (for the metadata). ``progress(stage, fraction)``."""
    t0 = time.perf_counter()
    if step < 1:
        raise InputError(f"--step {step}: expected at least 1")
    if "dsm" in formats and georef is None:
        raise InputError(f"--format dsm needs the map: {note or 'exported in the camera frame'}")
    if cell is not None and not (math.isfinite(cell) and cell > 0):
        raise InputError(f"--cell {cell:g}: expected a positive size")
    report = progress or (lambda stage, fraction: None)
    names = [_file_name(source, fmt) for fmt in formats] + [source.name + SIDECAR_SUFFIX]
    check_output_folder(out, "--out")  # the rule for outputs (rigkit.core.outputs)
    check_writable_folder(out, f"--out {out}")
    check_outputs(out, names, "--out", "export")
    report("counting points", 0.0)
    count = count_points(source.depth, step)
    if count == 0 and set(formats) - {"tif"}:
        raise InputError(f"{source.name}: the depth map has no estimated pixel to export")
    try:
        with terminate_as_interrupt(), staged_outputs(out, names, "--out", "export") as staging:
            clouds = [fmt for fmt in formats if fmt in CLOUDS]
            footprint = Footprint() if "dsm" in formats else None
            filled = _write_clouds(source, staging, clouds, count, step, georef, footprint,
                                   report)
            dsm = None
            if footprint is not None and georef is not None:
                dsm = _write_dsm(source, staging / _file_name(source, "dsm"), step, georef,
                                 footprint, cell, report)
            if "tif" in formats:
                write_tiff(staging / _file_name(source, "tif"), source,
                           lambda fraction: report("writing tif", fraction))
            meta = sidecar(source, georef, note=note, step=step, points=count, filled=filled,
                           files=names[:-1], dsm=dsm, time_utc=utc_now())
            (staging / names[-1]).write_text(dumps(meta), encoding="utf-8")
    except OSError as exc:
        raise InputError(f"{out}: cannot write the export ({exc.strerror or exc}); "
                         "nothing was written") from None
    report("done", 1.0)
    return Exported(
        files=tuple(out / name for name in names), points=count,
        median_z_m=_median(source.depth[::step, ::step]),
        frame=CAMERA_FRAME if georef is None else _map_frame(georef),
        georef=georef, seconds=time.perf_counter() - t0, note=note, filled=filled, dsm=dsm,
    )


def _file_name(source: DepthMap, fmt: str) -> str:
    return f"{source.name}.dsm.tif" if fmt == "dsm" else f"{source.name}.{fmt}"


def _write_clouds(source: DepthMap, folder: Path, formats: list[str], count: int,
                  step: int, georef: Georeference | None, footprint: Footprint | None,
                  report: Report) -> int | None:
    """Every point format from one pass over the map (which also gathers the DSM's
    footprint); the number of filled points (None: not known)."""
    if not formats and footprint is None:
        return _filled_count(source, step)
    with contextlib.ExitStack() as stack:
        writers = [stack.enter_context(_writer(folder / f"{source.name}.{fmt}", fmt, count,
                                               source, georef)) for fmt in formats]
        transform = georef.to_map if georef is not None else None
        stage = "writing " + ", ".join(formats) if formats else "measuring the DSM"
        filled = 0 if source.flags is not None else None
        for chunk in point_chunks(source, step, transform):
            for writer in writers:
                writer.write(chunk)
            if footprint is not None:
                footprint.add(chunk)
            if filled is not None and chunk.filled is not None:
                filled += int(chunk.filled.sum())
            report(stage, chunk.done)
    return filled


def _filled_count(source: DepthMap, step: int) -> int | None:
    """Filled points on the export's grid, without a pass over the points."""
    if source.flags is None:
        return None
    height, width = source.depth.shape
    total = 0
    for rows in row_blocks((height, width), step):
        marked = source.filled(rows, slice(None, None, step))
        assert marked is not None
        total += int((marked & estimated(source.depth[rows, ::step])).sum())
    return total


def _write_dsm(source: DepthMap, path: Path, step: int, georef: Georeference,
               footprint: Footprint, cell: float | None, report: Report) -> dict[str, Any]:
    """Grid the points (the second pass) and write the COG; the grid's description."""
    grid, how = footprint.grid(cell)
    z_unit = georef.map.crs.axis_info[-1].unit_conversion_factor
    gridder = Gridder(grid, georef.origin, georef.map.unit_m, float(z_unit))
    for chunk in point_chunks(source, step, georef.to_map):
        gridder.add(chunk)
        report("gridding the DSM", chunk.done)
    elevation, sigma = gridder.rasters()
    tags = {"RIGKIT_BANDS": "elevation (mean height of the points in a cell), sigma (one "
            "standard error of that height from the depth's error, see rigkit "
            "docs/outputs.md)", "RIGKIT_HEIGHTS": georef.map.heights,
            "RIGKIT_SOURCE": source.name}
    report("writing dsm", 0.5)
    write_dsm(path, elevation, sigma, grid, georef.crs, tags)
    report("writing dsm", 1.0)
    return {"file": path.name, "cell": grid.cell, "unit_m": georef.map.unit_m,
            "cell_chosen": how, "width": grid.width, "height": grid.height,
            "west": grid.west, "north": grid.north, "nodata": NODATA,
            "bands": ["elevation", "sigma"],
            "cells_with_points": int(np.isfinite(elevation).sum())}


def _writer(path: Path, fmt: str, count: int, source: DepthMap,
            georef: Georeference | None) -> Any:
    frame = CAMERA_FRAME if georef is None else _map_frame(georef)
    if fmt == "ply":
        comments = [f"rigkit export of {source.name} (rig {source.rig}, run {source.run_id})",
                    f"frame {frame}", "sigma: 1-sigma depth error, metres",
                    "red, green, blue: the left image's grey value"]
        if source.flags is not None:
            comments.append("filled: 1 where the depth was filled from a neighbour")
        return PlyWriter(path.open("xb"), count, double=georef is not None, comments=comments,
                         filled=source.flags is not None)
    reach = _reach_m(source) / (georef.map.unit_m if georef is not None else 1.0)
    origin = georef.origin if georef is not None else (0.0, 0.0, 0.0)
    header = las_header(origin, reach, georef.map.wkt1()[0] if georef is not None else None,
                        f"rigkit {source.name}")
    return LasWriter(path, header, compress=fmt == "laz")


def _reach_m(source: DepthMap) -> float:
    """How far from the camera the farthest point can be, metres: the largest depth
    times the longest ray (an image corner's), plus a margin for the map's curvature."""
    depth = source.depth
    deepest = max((float(depth[rows][estimated(depth[rows])].max(initial=0.0))
                   for rows in row_blocks(depth.shape, 1)), default=0.0)
    width, height = source.size
    corners = np.array([[0.0, 0.0], [width - 1, 0.0], [0.0, height - 1], [width - 1, height - 1]])
    longest = float(np.linalg.norm(source.lens.rays(corners), axis=1).max())
    return deepest * longest * 1.01 + 10.0


def _map_frame(georef: Georeference) -> str:
    on_map = georef.map
    return (f"{on_map.horizontal_code} ({on_map.horizontal.name}) + {on_map.vertical_name}: "
            "easting, northing, height")


def _median(depth: np.ndarray) -> float:
    """Median of the estimated depths, metres (one float32 copy of them)."""
    valid = depth[estimated(depth)]
    return float(np.median(valid, overwrite_input=True)) if valid.size else math.nan
