"""One export: a depth map to point clouds (PLY, LAS, LAZ) and a raster (TIFF), in the
left camera's frame or, for a session that knows where its tripod stood, on the map.

The map is read once, in chunks of rows (:func:`rigkit.export.points.point_chunks`), and
every point format is written from the same chunks; all files are staged in a hidden
folder inside the output folder and renamed into place together at the end
(:func:`rigkit.core.outputs.staged_outputs`), so a failure leaves no partial output, and
never over a file rigkit did not write nor inside a session's own parts.
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

from rigkit.core.files import check_writable_folder
from rigkit.core.outputs import check_output_folder, check_outputs, staged_outputs
from rigkit.core.signals import terminate_as_interrupt
from rigkit.errors import InputError
from rigkit.export.georef import MAX_RESIDUAL_DEG, Georeference, georeference
from rigkit.export.las import LasWriter, las_header
from rigkit.export.ply import PlyWriter
from rigkit.export.points import count_points, estimated, point_chunks, row_blocks
from rigkit.export.source import DepthMap, open_depth
from rigkit.export.tiff import write_tiff

FORMATS = ("ply", "las", "laz", "tif")
DEFAULT_FORMATS = ("ply", "las")
FRAMES = ("auto", "camera", "map")
CAMERA_FRAME = "left camera: x right, y down, z forward, metres"
EXPORT_DIR = "export"
"""Where the field TUI exports a session: ``SESSION/export/``."""

Report = Callable[[str, float], None]


@dataclass(frozen=True)
class Exported:
    """What an export wrote: ``files``; ``points`` per point cloud; ``median_z_m``, the
    median depth of the exported grid; ``frame`` in words; ``georef`` when on the map."""

    files: tuple[Path, ...]
    points: int
    median_z_m: float
    frame: str
    georef: Georeference | None
    seconds: float


def parse_formats(text: str) -> tuple[str, ...]:
    """``ply,las`` -> ("ply", "las"); InputError naming an unknown format."""
    formats = tuple(dict.fromkeys(f.strip().lower() for f in text.split(",") if f.strip()))
    unknown = [f for f in formats if f not in FORMATS]
    if unknown or not formats:
        raise InputError(f"--format {text!r}: choose from {', '.join(FORMATS)}")
    return formats


def export_path(path: Path, out: Path, formats: Sequence[str] = DEFAULT_FORMATS, *,
                step: int = 1, frame: str = "auto", max_residual_deg: float = MAX_RESIDUAL_DEG,
                progress: Report | None = None) -> Exported:
    """Export the session or depth map file at ``path`` into the folder ``out`` (see
    :func:`export_depth`). ``frame``: ``camera``, ``map`` (georeferenced; InputError if
    it cannot be), or ``auto``: on the map when the session has a tripod position."""
    if frame not in FRAMES:
        raise InputError(f"frame {frame!r}: choose from {', '.join(FRAMES)}")
    source = open_depth(path)
    on_map = frame == "map" or (frame == "auto" and source.session is not None
                                and source.session.tripod is not None)
    georef = georeference(source, max_residual_deg) if on_map else None
    return export_depth(source, out, formats, step=step, georef=georef, progress=progress)


def export_depth(source: DepthMap, out: Path, formats: Sequence[str], *, step: int = 1,
                 georef: Georeference | None = None, progress: Report | None = None
                 ) -> Exported:
    """Write ``source`` as ``<name>.<format>`` for each of ``formats`` into ``out``: a
    point per estimated pixel on every ``step``-th row and column, in the camera frame
    or, with ``georef``, in its UTM zone. ``progress(stage, fraction)`` as it goes."""
    t0 = time.perf_counter()
    if step < 1:
        raise InputError(f"--step {step}: expected at least 1")
    report = progress or (lambda stage, fraction: None)
    names = [f"{source.name}.{fmt}" for fmt in formats]
    check_output_folder(out, "--out")  # the rule for outputs (rigkit.core.outputs)
    check_writable_folder(out, f"--out {out}")
    check_outputs(out, names, "--out")
    report("counting points", 0.0)
    count = count_points(source.depth, step)
    if count == 0 and set(formats) - {"tif"}:
        raise InputError(f"{source.name}: the depth map has no estimated pixel to export")
    try:
        with terminate_as_interrupt(), staged_outputs(out, names, "--out") as staging:
            clouds = [fmt for fmt in formats if fmt != "tif"]
            if clouds:
                _write_clouds(source, staging, clouds, count, step, georef, report)
            if "tif" in formats:
                write_tiff(staging / f"{source.name}.tif", source,
                           lambda fraction: report("writing tif", fraction))
    except OSError as exc:
        raise InputError(f"{out}: cannot write the export ({exc.strerror or exc}); "
                         "nothing was written") from None
    report("done", 1.0)
    return Exported(
        files=tuple(out / name for name in names), points=count,
        median_z_m=_median(source.depth[::step, ::step]),
        frame=CAMERA_FRAME if georef is None else _map_frame(georef),
        georef=georef, seconds=time.perf_counter() - t0,
    )


def _write_clouds(source: DepthMap, folder: Path, formats: list[str], count: int,
                  step: int, georef: Georeference | None, report: Report) -> None:
    """Every point format from one pass over the map."""
    with contextlib.ExitStack() as stack:
        writers = [stack.enter_context(_writer(folder / f"{source.name}.{fmt}", fmt, count,
                                               source, georef)) for fmt in formats]
        transform = georef.to_map if georef is not None else None
        for chunk in point_chunks(source, step, transform):
            for writer in writers:
                writer.write(chunk)
            report("writing " + ", ".join(formats), chunk.done)


def _writer(path: Path, fmt: str, count: int, source: DepthMap,
            georef: Georeference | None) -> Any:
    frame = CAMERA_FRAME if georef is None else _map_frame(georef)
    if fmt == "ply":
        comments = [f"rigkit export of {source.name} (rig {source.rig}, run {source.run_id})",
                    f"frame {frame}", "sigma: 1-sigma depth error, metres",
                    "red, green, blue: the left image's grey value"]
        return PlyWriter(path.open("xb"), count, double=georef is not None, comments=comments)
    reach = _reach_m(source)
    origin = georef.origin if georef is not None else (0.0, 0.0, 0.0)
    header = las_header(origin, reach, georef.crs if georef is not None else None,
                        f"rigkit {source.name}")
    return LasWriter(path, header, compress=fmt == "laz")


def _reach_m(source: DepthMap) -> float:
    """How far from the camera the farthest point can be, metres: the largest depth
    times the longest ray (the image corner's), plus a margin for the map's curvature."""
    depth = source.depth
    deepest = max((float(depth[rows][estimated(depth[rows])].max(initial=0.0))
                   for rows in row_blocks(depth.shape, 1)), default=0.0)
    width, height = source.size
    corner = math.hypot(max(source.cx, width - source.cx), max(source.cy, height - source.cy))
    return deepest * math.hypot(1.0, corner / source.f) * 1.01 + 10.0


def _map_frame(georef: Georeference) -> str:
    crs = georef.crs
    return f"EPSG:{georef.epsg} ({crs.name}): easting, northing, height, metres"


def _median(depth: np.ndarray) -> float:
    """Median of the estimated depths, metres (one float32 copy of them)."""
    valid = depth[estimated(depth)]
    return float(np.median(valid, overwrite_input=True)) if valid.size else math.nan
