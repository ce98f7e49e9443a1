"""What an export reads: a depth map, its sigma, the left image's grey values, what each
pixel's depth rests on, and the run that made it (its lens above all,
:mod:`rigkit.export.runinfo`), from a processed session or from ``rigkit depth``'s files.

A session's ``results/`` holds ``depth.npy``, ``sigma.npy``, ``grey.png``, ``flags.npy``
and ``depth.json``; ``rigkit depth --out D.npy`` writes ``D.npy``, ``D.sigma.npy``,
``D.grey.png``, ``D.flags.npy`` and ``D.json``. The maps are memory-mapped, not read
whole. Results from before rigkit wrote the flags export without them (no point is then
marked as filled, and the metadata says that it is not known).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from rigkit.capture.model import Session
from rigkit.capture.results import RunFiles, RunRecord, read_record, stale_results
from rigkit.capture.session import is_session, load_session
from rigkit.core.files import read_npy
from rigkit.core.safefs import check_regular, read_input, real_folder
from rigkit.errors import InputError
from rigkit.export.runinfo import RunInfo
from rigkit.imagefile.imagesize import MAX_FRAME_BYTES, MAX_FRAME_PIXELS
from rigkit.pipeline.estimate import FLAG_FILLED
from rigkit.pipeline.lens import Lens


@dataclass(frozen=True)
class DepthMap:
    """One depth map ready to export.

    ``depth``: (H, W) float32, metres, z along the left camera's optical axis, NaN = no
    estimate; ``sigma``: (H, W) float32, metres, its one standard error; ``grey``: (H, W)
    uint8, the left image the depth map lies on. ``flags``: (H, W) uint8, what each
    pixel's depth rests on (``rigkit.pipeline.estimate.FLAG_*`` bits), None for results
    from before rigkit wrote them. ``run``: the run that made it, with the lens every
    pixel is back-projected through. ``name`` names the exported files; ``session`` the
    session the map belongs to, if any (its tripod position and targets georeference it).
    """

    depth: np.ndarray
    sigma: np.ndarray
    grey: np.ndarray
    name: str
    run: RunInfo
    flags: np.ndarray | None = None
    session: Session | None = None

    @property
    def size(self) -> tuple[int, int]:
        """(width, height) in px."""
        return self.depth.shape[1], self.depth.shape[0]

    @property
    def lens(self) -> Lens:
        """The left view's lens, through which pixels are back-projected."""
        return self.run.lens

    @property
    def rig(self) -> str:
        return self.run.rig

    @property
    def run_id(self) -> str | None:
        return self.run.run_id

    def filled(self, rows: slice, cols: slice) -> np.ndarray | None:
        """Which pixels of ``[rows, cols]`` the pipeline filled from a neighbour rather
        than matched, (h, w) bool; None when the results do not say."""
        if self.flags is None:
            return None
        return (np.asarray(self.flags[rows, cols]) & FLAG_FILLED) != 0


def open_depth(path: Path) -> DepthMap:
    """A session folder's latest results, or a depth map file ``D.npy`` and its sidecars;
    InputError naming what is missing."""
    path = Path(path)
    if path.is_dir():
        return session_depth(path)
    if path.suffix == ".npy":
        return file_depth(path)
    raise InputError(f"{path}: expected a session folder or a depth map (.npy) written by "
                     "rigkit depth")


def session_depth(path: Path) -> DepthMap:
    """The latest ``rigkit process`` results of the session at ``path``. Read without
    the session's lock (results are swapped in whole); the run's record is read before
    and after, so a run swapped in meanwhile is noticed rather than mixed. The depth map
    is back-projected through the lens the run used (its record's)."""
    if not is_session(path):
        raise InputError(f"{path}: not a session folder (no session.yaml)")
    session = load_session(path)
    files = RunFiles.of_session(path)
    if not files.depth.is_file():
        raise InputError(f"{path}: no results yet; run `rigkit process {path}` first")
    real_folder(files.depth.parent)  # the session's own: no link leads the export elsewhere
    for name in (files.depth, files.sigma, files.grey, files.record):
        check_regular(name)
    if files.flags.exists():
        check_regular(files.flags)
    stale = stale_results(session, with_targets=False)  # a depth map of other frames or rig
    if stale is not None:
        raise InputError(f"{path}: {stale} (rigkit process {path}) before exporting")
    record = read_record(files.record)
    depth_map = _depth_map(files, record, f"rigkit process {path}", session.name, session)
    if read_record(files.record).run_id != record.run_id:
        raise InputError(f"{path}: results were replaced while being read (a run just "
                         "finished); export again")
    return depth_map


def file_depth(path: Path) -> DepthMap:
    """``rigkit depth``'s ``D.npy`` with ``D.sigma.npy``, ``D.grey.png``, ``D.flags.npy``
    and ``D.json`` beside it; the run (and its lens) from ``D.json``, its record."""
    files = RunFiles.beside(path)
    record = read_record(files.record)
    return _depth_map(files, record, f"rigkit depth ... --out {path}",
                      path.with_suffix("").name)


def _depth_map(files: RunFiles, record: RunRecord, remake: str, name: str,
               session: Session | None = None) -> DepthMap:
    """The run's maps with its record's lens (:class:`rigkit.export.runinfo.RunInfo`);
    InputError where the maps are not of the size the record says the run made."""
    arrays = _maps(files, remake)
    height, width = arrays[0].shape
    if (width, height) != record.image_size_px:
        raise InputError(f"{files.depth}: the depth map is {width}x{height} px, its record "
                         f"says {record.image_size_px[0]}x{record.image_size_px[1]} px")
    flags = _flags(files.flags, arrays[0].shape)
    return DepthMap(*arrays, name=name, run=RunInfo.of(record), flags=flags, session=session)


def _flags(path: Path, shape: tuple[int, ...]) -> np.ndarray | None:
    """The pipeline's flags (memory-mapped), None where the results have none."""
    if not path.exists():
        return None
    flags = _npy(path, np.uint8, "uint8 flags")
    if flags.shape != shape:
        raise InputError(f"{path}: {flags.shape}, the depth map is {shape}")
    return flags


def _maps(files: RunFiles, remake: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Depth and sigma memory-mapped, grey read; all (H, W) and of one size, no larger
    than the largest frame (a map beyond it is refused before it is read)."""
    depth_path, grey_path = files.depth, files.grey
    depth, sigma = (_npy(p) for p in (files.depth, files.sigma))
    if depth.size > MAX_FRAME_PIXELS:
        raise InputError(f"{depth_path}: a {'x'.join(map(str, depth.shape[::-1]))} map, "
                         f"beyond the {MAX_FRAME_PIXELS / 1e6:.0f} MP of the largest frame")
    if not grey_path.is_file():
        raise InputError(f"{grey_path}: missing (written since rigkit records the grey "
                         f"values for export); run `{remake}` again")
    # read by Python (no file name reaches OpenCV), never a FIFO, at most a frame's size
    data = np.frombuffer(read_input(grey_path, MAX_FRAME_BYTES, "a grey image"), np.uint8)
    grey = cv2.imdecode(data, cv2.IMREAD_GRAYSCALE) if data.size else None
    if grey is None:
        raise InputError(f"{grey_path}: cannot read the image")
    if depth.ndim != 2 or sigma.shape != depth.shape or grey.shape != depth.shape:
        raise InputError(f"{depth_path}: depth {depth.shape}, sigma {sigma.shape} and grey "
                         f"{grey.shape} must be one (H, W) size")
    return depth, sigma, grey


def _npy(path: Path, dtype: type = np.float32, what: str = "float32 metres") -> np.ndarray:
    try:
        array = read_npy(path)
    except FileNotFoundError:
        raise InputError(f"{path}: missing") from None
    if array.dtype != dtype:
        raise InputError(f"{path}: {array.dtype} values, expected {what}")
    return array
