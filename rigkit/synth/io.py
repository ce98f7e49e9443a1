"""Scene folders: what ``rigkit synth`` writes and ``rigkit eval`` reads.

Layout of ``SCENE_DIR/`` (documented in docs/synthetic-scenes.md)::

    left.png  right.png  back.png        8-bit grey images (the first frame of each position)
    left-2.png ... back-N.png            further frames of a burst (``burst`` > 1)
    scene.yaml                           rig, cameras (K, R, C), generator parameters
    ground_truth/depth_left.npy          (H, W) float32, metres, z in the left camera, NaN = no hit
    ground_truth/depth_right.npy         same for the right camera (for visibility)
    ground_truth/depth_back.npy          same for the back camera
    ground_truth/flat_left.npy           (H, W) bool, left pixels whose surface has no texture
                                         (a plain wall, an empty backdrop: Layers.flat)
    ground_truth/moved_left.npy          (H, W) bool, left pixels a mover covers in any view
    ground_truth/shadow_changed_left.npy (H, W) bool, left pixels whose cloud shadow changes
                                         (both only for scenes with movers or cloud shadows;
                                         rigkit.synth.changes)
"""

from __future__ import annotations

import re
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass, field, fields
from pathlib import Path

import numpy as np

from rigkit.core.files import read_npy, write_npy, write_png, write_text
from rigkit.core.outputs import LEDGER, check_outputs, record_outputs
from rigkit.core.yamlfile import dump_yaml, read_strict_yaml
from rigkit.errors import InputError
from rigkit.geometry import NO_DISTORTION, Camera, distortion_coefficients
from rigkit.imagefile.imagesize import MAX_FRAME_PIXELS
from rigkit.synth.changes import moved_left, shadow_changed_left
from rigkit.synth.render import Layers, expose, render_layers
from rigkit.synth.scene import Scene, SynthParams
from rigkit.synth.shapes import VIEWS

SCENE_FILE = "scene.yaml"
MOVED_FILE = "moved_left.npy"
SHADOW_FILE = "shadow_changed_left.npy"
FLAT_FILE = "flat_left.npy"


def _camera_dict(cam: Camera, euler: tuple[float, float, float]) -> dict[str, object]:
    return {
        "resolution": [cam.width, cam.height],
        "intrinsics": {
            "fx": float(cam.K[0, 0]),
            "fy": float(cam.K[1, 1]),
            "cx": float(cam.K[0, 2]),
            "cy": float(cam.K[1, 2]),
        },
        "R_world_to_camera": [[float(x) for x in row] for row in cam.R],
        "center_m": [float(x) for x in cam.C],
        "euler_xyz_deg": list(euler),
        "distortion_k1_k2_p1_p2_k3": list(cam.distortion),
    }


def frame_name(view: str, frame: int) -> str:
    """File name of ``frame`` (0-based) of a burst at position ``view``."""
    return f"{view}.png" if frame == 0 else f"{view}-{frame + 1}.png"


SCENE_FORMAT = "rigkit-synthetic-scene/1"
_WRITTEN = re.compile(r"(left|right|back)(-[0-9]+)?\.png|scene\.yaml|ground_truth")
"""The names :func:`write_scene` writes in a scene folder."""


def check_out_folder(out_dir: Path, new: bool = False) -> None:
    """InputError unless a rendering may go into ``out_dir``, checked before anything is
    written there: a folder that is missing or empty, or (unless ``new``) a scene folder
    rendered before, holding nothing but what a rendering writes (its ``scene.yaml``
    says so), whose files the new rendering replaces. A folder holding anything else is
    someone's: nothing in it is written over."""
    out_dir = Path(out_dir)
    if not out_dir.exists():
        return
    if not out_dir.is_dir():
        raise InputError(f"{out_dir}: a file, not a folder; give a new or empty folder")
    names = sorted(p.name for p in out_dir.iterdir())
    if not names:
        return
    shown = ", ".join(names[:3]) + (", ..." if len(names) > 3 else "")
    if new:
        raise InputError(f"{out_dir}: holds files already ({shown}); a synthetic session "
                         "is written into a new or empty folder")
    foreign = [n for n in names if not _WRITTEN.fullmatch(n) and n != LEDGER]
    truth = out_dir / "ground_truth"
    if (foreign or not _is_rendered(out_dir / SCENE_FILE)
            or truth.is_symlink() or (truth.exists() and not truth.is_dir())):
        raise InputError(f"{out_dir}: holds files that are no scene rendered by rigkit synth "
                         f"({shown}); give a new or empty folder")
    for folder in (out_dir, truth):  # each file it replaces one rigkit wrote (its ledger)
        if folder.is_dir():
            check_outputs(folder, [p.name for p in folder.iterdir()
                                   if p.name not in (LEDGER, "ground_truth")], "OUT_DIR",
                          "synth")


def _is_rendered(meta: Path) -> bool:
    """Whether ``meta`` is a regular file that :func:`write_scene` wrote (its format)."""
    if meta.is_symlink() or not meta.is_file():
        return False
    try:
        data = read_strict_yaml(meta, "scene description")
    except InputError:
        return False
    return isinstance(data, dict) and data.get("format") == SCENE_FORMAT


def write_scene(
    scene: Scene, out_dir: Path, progress: Callable[[str, float], None] | None = None
) -> dict[str, float]:
    """Render all three views of ``scene`` into ``out_dir`` (:func:`check_out_folder`
    first). Returns seconds per view."""
    check_out_folder(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    truth = out_dir / "ground_truth"
    truth.mkdir(exist_ok=True)
    written: list[Path] = []  # recorded as rigkit's (rigkit.core.outputs), whatever happens:
    # a name is listed before its file is written, and a file that is not there is not
    # recorded
    try:
        timings = _write_views(scene, out_dir, progress, written)
    finally:
        for folder in (out_dir, truth):
            record_outputs(folder, [p.name for p in written if p.parent == folder], "synth")
    return timings


def _write_views(scene: Scene, out_dir: Path, progress: Callable[[str, float], None] | None,
                 written: list[Path]) -> dict[str, float]:
    """:func:`write_scene`'s files, each added to ``written`` once it is in place."""
    truth = out_dir / "ground_truth"
    timings: dict[str, float] = {}
    left: Layers | None = None
    for name in VIEWS:
        t0 = time.perf_counter()
        cb = (lambda frac, n=name: progress(n, frac)) if progress else None
        layers = render_layers(scene, name, cb)
        for k in range(scene.params.burst):
            written.append(out_dir / frame_name(name, k))
            write_png(written[-1], expose(scene, name, layers.radiance, frame=k), compression=3)
        written.append(truth / f"depth_{name}.npy")
        write_npy(written[-1], layers.depth)
        if name == "left":
            left = layers
            written.append(truth / FLAT_FILE)
            write_npy(written[-1], layers.flat())
        timings[name] = time.perf_counter() - t0
    if left is not None and (scene.movers or scene.shadows):
        written += [truth / MOVED_FILE, truth / SHADOW_FILE]
        write_npy(truth / MOVED_FILE, moved_left(scene, left.surface, left.depth))
        write_npy(truth / SHADOW_FILE, shadow_changed_left(scene, left.depth))
    meta = {
        "format": SCENE_FORMAT,
        "seed": scene.seed,
        "focal_px": scene.params.focal_px,
        "baseline_lr_m": scene.params.baseline_lr_m,
        "baseline_lb_m": scene.params.baseline_lb_m,
        "params": asdict(scene.params),
        "cameras": {n: _camera_dict(scene.cameras[n], scene.euler_deg[n]) for n in VIEWS},
        "gains": scene.gains,
        "geometry": scene.description(),
    }
    written.append(out_dir / SCENE_FILE)
    write_text(out_dir / SCENE_FILE, dump_yaml(meta))
    return timings


@dataclass(frozen=True)
class SceneTruth:
    """Ground truth of a scene folder, as ``rigkit eval`` needs it, with the generator's
    ``seed`` and ``params`` that made it (defaults where the folder does not say)."""

    path: Path
    cameras: dict[str, Camera]
    focal_px: float
    baseline_lr_m: float
    baseline_lb_m: float
    seed: int = 0
    params: SynthParams = field(default_factory=SynthParams)

    def depth(self, view: str) -> np.ndarray:
        """(H, W) float32, metres, z in ``view``'s camera frame, NaN where nothing was hit."""
        p = self.path / "ground_truth" / f"depth_{view}.npy"
        if not p.is_file():
            raise InputError(f"{self.path}: missing ground truth {p.name}")
        return _truth(p, np.floating, 2)

    def changes(self) -> tuple[np.ndarray, np.ndarray] | None:
        """(moved, shadow_changed), each (H, W) bool over the left view
        (:mod:`rigkit.synth.changes`), or None for a scene where nothing moves."""
        folder = self.path / "ground_truth"
        if not (folder / MOVED_FILE).is_file():
            return None
        return _truth(folder / MOVED_FILE, np.bool_, 2), _truth(folder / SHADOW_FILE, np.bool_, 2)

    def flat(self) -> np.ndarray | None:
        """(H, W) bool, left pixels whose surface has no texture (:meth:`Layers.flat`),
        or None for a scene folder written before rigkit recorded them."""
        path = self.path / "ground_truth" / FLAT_FILE
        return _truth(path, np.bool_, 2) if path.is_file() else None

    def image_path(self, view: str) -> Path:
        """The rendered image; in a synthetic session it lives in ``raw/``."""
        rendered = self.path / f"{view}.png"
        return rendered if rendered.is_file() else self.path / "raw" / f"{view}.png"

    def frame_paths(self, view: str) -> list[Path]:
        """Every frame of a burst at ``view`` (just :meth:`image_path` for a single one)."""
        paths = [self.image_path(view)]
        while (nxt := paths[0].parent / frame_name(view, len(paths))).is_file():
            paths.append(nxt)
        return paths


def _params(values: dict) -> SynthParams:
    """The generator's settings as recorded in scene.yaml (names it does not know, from
    another version, are left out)."""
    known = {f.name for f in fields(SynthParams)}
    kw = {k: v for k, v in values.items() if k in known}
    if "distortion" in kw:
        kw["distortion"] = distortion_coefficients(kw["distortion"])
    return SynthParams(**kw)


def _truth(path: Path, kind: type, ndim: int) -> np.ndarray:
    """A ground-truth array of ``kind`` (a NumPy scalar type) and ``ndim`` dimensions,
    no larger than the largest frame; InputError naming the file where it is none (said
    from its header, before it is read)."""
    try:
        array = read_npy(path)
    except FileNotFoundError:
        raise InputError(f"{path}: missing ground truth") from None
    if array.ndim != ndim \
            or not np.issubdtype(array.dtype, kind):
        raise InputError(f"{path}: not ground truth as rigkit synth writes it "
                         f"({getattr(array, 'dtype', '?')}, {getattr(array, 'ndim', '?')} axes)")
    if array.size > MAX_FRAME_PIXELS:
        raise InputError(f"{path}: {array.size:,} values, beyond the largest frame")
    return np.array(array)


def load_scene(path: str | Path) -> SceneTruth:
    """Read ``scene.yaml`` of a scene folder written by :func:`write_scene`."""
    path = Path(path)
    meta_path = path / SCENE_FILE
    if not meta_path.is_file():
        raise InputError(f"{path}: not a scene folder (no {SCENE_FILE})")
    try:
        meta = read_strict_yaml(meta_path, "scene description")
        cams = {}
        for name in VIEWS:
            c = meta["cameras"][name]
            k = c["intrinsics"]
            K = np.array([[k["fx"], 0, k["cx"]], [0, k["fy"], k["cy"]], [0, 0, 1]], float)
            w, h = c["resolution"]
            cams[name] = Camera(
                K=K,
                R=np.array(c["R_world_to_camera"], float),
                C=np.array(c["center_m"], float),
                width=int(w),
                height=int(h),
                distortion=distortion_coefficients(
                    c.get("distortion_k1_k2_p1_p2_k3", NO_DISTORTION)
                ),
            )
        return SceneTruth(
            path=path,
            cameras=cams,
            focal_px=float(meta["focal_px"]),
            baseline_lr_m=float(meta["baseline_lr_m"]),
            baseline_lb_m=float(meta["baseline_lb_m"]),
            seed=int(meta.get("seed", 0)),
            params=_params(meta.get("params") or {}),
        )
    except (KeyError, TypeError, ValueError) as exc:
        raise InputError(f"{meta_path}: malformed scene description ({exc!r})") from None
