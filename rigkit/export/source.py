"""What an export reads: a depth map, its sigma, the left image's grey values and the
left camera's intrinsics, from a processed session or from ``rigkit depth``'s files.

A session's ``results/`` holds ``depth.npy``, ``sigma.npy``, ``grey.png`` and
``depth.json``; ``rigkit depth --out D.npy`` writes ``D.npy``, ``D.sigma.npy``,
``D.grey.png`` and ``D.json``. The maps are memory-mapped, not read whole.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from rigkit.capture.model import RESULTS_DIR, Session
from rigkit.capture.results import stale_results
from rigkit.capture.session import is_session, load_session
from rigkit.core.safefs import check_regular, real_folder
from rigkit.errors import InputError


@dataclass(frozen=True)
class DepthMap:
    """One depth map ready to export.

    ``depth``: (H, W) float32, metres, z along the left camera's optical axis, NaN = no
    estimate; ``sigma``: (H, W) float32, metres, its one standard error; ``grey``: (H, W)
    uint8, the left image the depth map lies on. ``f``, ``cx``, ``cy``: the left camera's
    pinhole intrinsics in px, pixel centres at integers
    (:meth:`rigkit.rig.profile.RigProfile.intrinsics`, as the pipeline and the laser
    comparison take them). ``name`` names the exported files; ``rig`` the rig profile; ``run_id``
    the processing run (None for ``rigkit depth``'s files); ``session`` the session the
    map belongs to, if any (its tripod position and targets georeference it).
    """

    depth: np.ndarray
    sigma: np.ndarray
    grey: np.ndarray
    f: float
    cx: float
    cy: float
    name: str
    rig: str
    run_id: str | None = None
    session: Session | None = None

    @property
    def size(self) -> tuple[int, int]:
        """(width, height) in px."""
        return self.depth.shape[1], self.depth.shape[0]


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
    the session's lock (results are swapped in whole); the run id is read before and
    after, so a run swapped in meanwhile is noticed rather than mixed."""
    if not is_session(path):
        raise InputError(f"{path}: not a session folder (no session.yaml)")
    session = load_session(path)
    results = path / RESULTS_DIR
    if not (results / "depth.npy").is_file():
        raise InputError(f"{path}: no results yet; run `rigkit process {path}` first")
    real_folder(results)  # the session's own: no link leads the export elsewhere
    for name in ("depth.npy", "sigma.npy", "grey.png", "depth.json"):
        check_regular(results / name)
    stale = stale_results(session, with_targets=False)  # a depth map of other frames or rig
    if stale is not None:
        raise InputError(f"{path}: {stale} (rigkit process {path}) before exporting")
    run_id = _meta(results / "depth.json").get("run_id")
    arrays = _maps(results / "depth.npy", results / "sigma.npy", results / "grey.png",
                   f"rigkit process {path}")
    if _meta(results / "depth.json").get("run_id") != run_id:
        raise InputError(f"{path}: results were replaced while being read (a run just "
                         "finished); export again")
    rig = session.rig()
    camera = rig.intrinsics((arrays[0].shape[1], arrays[0].shape[0]))
    return DepthMap(*arrays, f=camera.focal_px, cx=camera.cx_px, cy=camera.cy_px,
                    name=session.name, rig=rig.name,
                    run_id=run_id, session=session)


def file_depth(path: Path) -> DepthMap:
    """``rigkit depth``'s ``D.npy`` with ``D.sigma.npy``, ``D.grey.png`` and ``D.json``
    beside it. The intrinsics are ``D.json``'s ``left_camera_px``; a ``D.json`` written
    before rigkit recorded them gives its focal length and the image centre."""
    stem = path.with_suffix("")
    meta = _meta(stem.with_suffix(".json"))
    arrays = _maps(path, Path(f"{stem}.sigma.npy"), Path(f"{stem}.grey.png"),
                   "rigkit depth ... --out " + str(path))
    height, width = arrays[0].shape
    try:
        camera = meta.get("left_camera_px") or {
            "f": meta["rig"]["focal_px"], "cx": (width - 1) / 2, "cy": (height - 1) / 2}
        f, cx, cy = (float(camera[k]) for k in ("f", "cx", "cy"))
        rig = str(meta["rig"]["name"])
    except (KeyError, TypeError, ValueError):
        raise InputError(f"{stem}.json: no rig focal length (not written by rigkit depth?)"
                         ) from None
    return DepthMap(*arrays, f=f, cx=cx, cy=cy, name=stem.name, rig=rig)


def _meta(path: Path) -> dict[str, Any]:
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise InputError(f"{path}: missing (written with the depth map)") from None
    except (OSError, ValueError) as exc:
        raise InputError(f"{path}: cannot read ({exc})") from None
    if not isinstance(data, dict):
        raise InputError(f"{path}: not a depth map's metadata")
    return data


def _maps(depth_path: Path, sigma_path: Path, grey_path: Path,
          remake: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Depth and sigma memory-mapped, grey read; all (H, W) and of one size."""
    depth, sigma = (_npy(p) for p in (depth_path, sigma_path))
    if not grey_path.is_file():
        raise InputError(f"{grey_path}: missing (written since rigkit records the grey "
                         f"values for export); run `{remake}` again")
    data = np.fromfile(grey_path, np.uint8)  # read by Python: no file name reaches OpenCV
    grey = cv2.imdecode(data, cv2.IMREAD_GRAYSCALE) if data.size else None
    if grey is None:
        raise InputError(f"{grey_path}: cannot read the image")
    if depth.ndim != 2 or sigma.shape != depth.shape or grey.shape != depth.shape:
        raise InputError(f"{depth_path}: depth {depth.shape}, sigma {sigma.shape} and grey "
                         f"{grey.shape} must be one (H, W) size")
    return depth, sigma, grey


def _npy(path: Path) -> np.ndarray:
    try:
        array = np.load(path, mmap_mode="r")
    except FileNotFoundError:
        raise InputError(f"{path}: missing") from None
    except (OSError, ValueError) as exc:
        raise InputError(f"{path}: not a NumPy array file ({exc})") from None
    if array.dtype != np.float32:
        raise InputError(f"{path}: {array.dtype} values, expected float32 metres")
    return array
