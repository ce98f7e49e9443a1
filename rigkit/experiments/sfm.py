"""The SfM+MVS baseline: COLMAP's incremental SfM (pycolmap) on the three views, then a
dense step on the CPU with the poses it recovered.

* SfM: the left/right and left/back matches (the same sub-pixel matches the other
  methods use; right/back matches through shared left points) go into a COLMAP
  database with the true pinhole intrinsics of each camera, held fixed. COLMAP's
  triangulation-angle thresholds are meant for wide baselines and reject a 1/150
  baseline (~0.38 deg): they are lowered to ``MIN_TRI_ANGLE_DEG``, and the focal-length
  sanity check (f/W ~ 9.5 here) is widened. COLMAP's gauge is free; the reconstruction
  is expressed in the left camera's frame and scaled so that the left-right distance
  is the true ``C_lr`` (paper, sec. 5.2).
* Dense: pycolmap's PatchMatch stereo needs CUDA, so the pair is rectified with the
  recovered poses (Fusiello, Trucco & Verri 2000: both views turned to a common frame
  whose x axis is the baseline) and rigkit's matcher gives the disparity; each left
  pixel is triangulated with the recovered geometry.

pycolmap is an optional dependency (``pip install 'rigkit[experiments]'``).
"""

from __future__ import annotations

import tempfile
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from rigkit.errors import InputError, PipelineError
from rigkit.experiments.common import dense_disparity, left_grid, on_canvas
from rigkit.pipeline.features import Matches
from rigkit.pipeline.stereo import StereoMatcher

MIN_TRI_ANGLE_DEG = 0.05  # COLMAP defaults: 16 (initial pair), 1.5 (triangulation, filter)
VIEWS = ("left", "right", "back")


@dataclass(frozen=True)
class RigPoses:
    """Recovered poses in the left camera's frame, metres: ``R[v]`` (3, 3) world ->
    camera ``v``, ``C[v]`` (3,) its centre; the left camera is (I, 0)."""

    R: dict[str, np.ndarray]
    C: dict[str, np.ndarray]


def _pycolmap():
    try:
        import pycolmap
    except ImportError:
        raise InputError(
            "sfm-mvs needs pycolmap: pip install 'rigkit[experiments]'"
        ) from None
    pycolmap.logging.minloglevel = 2  # errors only: COLMAP logs every step at INFO
    return pycolmap


def _tracks(m_lr: Matches, m_lb: Matches) -> tuple[dict[str, np.ndarray], dict]:
    """Keypoints per view ((N, 2) px) and match index pairs per view pair ((M, 2) int).
    The left keypoints are the union of both match sets' left points."""
    left, inv = np.unique(np.vstack([m_lr.left, m_lb.left]), axis=0, return_inverse=True)
    il_r, il_b = inv[: len(m_lr.left)], inv[len(m_lr.left) :]
    right_of = dict(zip(il_r.tolist(), range(len(il_r)), strict=True))
    rb = [(right_of[k], j) for j, k in enumerate(il_b.tolist()) if k in right_of]
    keypoints = {"left": left, "right": m_lr.other, "back": m_lb.other}
    pairs = {
        ("left", "right"): np.column_stack([il_r, np.arange(len(il_r))]),
        ("left", "back"): np.column_stack([il_b, np.arange(len(il_b))]),
        ("right", "back"): np.array(rb, dtype=np.int64).reshape(-1, 2),
    }
    return keypoints, pairs


def _write_database(
    work: Path, images: dict[str, np.ndarray], K: dict[str, np.ndarray], m_lr: Matches,
    m_lb: Matches,
) -> Path:
    """A COLMAP database with the images, fixed true intrinsics, keypoints and matches.
    COLMAP's pixel centres are at +0.5, rigkit's at integers."""
    pc = _pycolmap()
    (work / "images").mkdir()
    for v, img in images.items():
        grey = np.clip(np.rint(img), 0, 255).astype(np.uint8)
        cv2.imwrite(str(work / "images" / f"{v}.png"), grey)
    db_path = work / "database.db"
    pc.Database.open(db_path).close()
    pc.import_images(db_path, work / "images", pc.CameraMode.PER_IMAGE)
    keypoints, pairs = _tracks(m_lr, m_lb)
    db = pc.Database.open(db_path)
    try:
        ids = {im.name.removesuffix(".png"): im for im in db.read_all_images()}
        for v, im in ids.items():
            h, w = images[v].shape
            cam = pc.Camera.create_from_model_name(im.camera_id, "PINHOLE", K[v][0, 0], w, h)
            cam.params = [K[v][0, 0], K[v][1, 1], K[v][0, 2] + 0.5, K[v][1, 2] + 0.5]
            cam.has_prior_focal_length = True
            db.update_camera(cam)
            db.write_keypoints(im.image_id, (keypoints[v] + 0.5).astype(np.float32))
        for (a, b), m in pairs.items():
            db.write_matches(ids[a].image_id, ids[b].image_id, m.astype(np.uint32))
    finally:
        db.close()
    (work / "pairs.txt").write_text("".join(f"{a}.png {b}.png\n" for a, b in pairs))
    pc.verify_matches(db_path, work / "pairs.txt")
    return db_path


def _mapper_options(rng: np.random.Generator):
    pc = _pycolmap()
    o = pc.IncrementalPipelineOptions()
    o.random_seed = int(rng.integers(2**31))
    o.num_threads = 1
    o.ba_refine_focal_length = False
    o.ba_refine_principal_point = False
    o.ba_refine_extra_params = False
    o.mapper.init_min_tri_angle = MIN_TRI_ANGLE_DEG
    o.mapper.filter_min_tri_angle = MIN_TRI_ANGLE_DEG
    o.mapper.ba_local_min_tri_angle = MIN_TRI_ANGLE_DEG
    o.triangulation.min_angle = MIN_TRI_ANGLE_DEG
    for opts in (o, o.mapper, o.triangulation):
        opts.max_focal_length_ratio = 100.0
    return o


def colmap_poses(
    images: dict[str, np.ndarray],
    K: dict[str, np.ndarray],
    m_lr: Matches,
    m_lb: Matches,
    c_lr: float,
    rng: np.random.Generator,
) -> RigPoses:
    """Incremental SfM of the three views (``images``: (H, W) float32 grey, ``K``: (3, 3)
    true intrinsics, rigkit pixel convention); poses in the left frame, scaled so that
    the right centre is ``c_lr`` m from the left one. Raises PipelineError when COLMAP
    does not register the left and right views in one model."""
    pc = _pycolmap()
    with tempfile.TemporaryDirectory(prefix="rigkit-colmap-") as tmp:
        work = Path(tmp)
        db_path = _write_database(work, images, K, m_lr, m_lb)
        (work / "sparse").mkdir()
        models = pc.incremental_mapping(
            db_path, work / "images", work / "sparse", _mapper_options(rng)
        )
    for rec in models.values():
        got = {im.name.removesuffix(".png"): im.cam_from_world() for im in rec.images.values()}
        if "left" in got and "right" in got:
            return _to_left_frame(got, c_lr)
    raise PipelineError("sfm-mvs: COLMAP did not register the left and right views together")


def _to_left_frame(cam_from_world: dict, c_lr: float) -> RigPoses:
    """COLMAP poses -> (R world->camera, centre) with the left camera as the world."""
    R0 = cam_from_world["left"].rotation.matrix()
    t0 = np.asarray(cam_from_world["left"].translation)
    C0 = -R0.T @ t0
    R, C = {}, {}
    for v, p in cam_from_world.items():
        Rv, tv = p.rotation.matrix(), np.asarray(p.translation)
        R[v] = Rv @ R0.T
        C[v] = R0 @ (-Rv.T @ tv - C0)
    norm = float(np.linalg.norm(C["right"]))
    if not norm > 0:
        raise PipelineError("sfm-mvs: COLMAP put the left and right cameras in one place")
    return RigPoses(R, {v: c * c_lr / norm for v, c in C.items()})


def calibrated_rectification(
    K_left: np.ndarray, K_right: np.ndarray, R_right: np.ndarray, C_right: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Rectify with known poses (Fusiello et al. 2000): returns (R_rect (3, 3) left frame
    -> rectified frame, H_left, H_right (3, 3) original -> rectified pixels). The
    rectified x axis is the baseline; both views use ``K_left``."""
    x = C_right / np.linalg.norm(C_right)
    y = np.cross([0.0, 0.0, 1.0], x)
    y /= np.linalg.norm(y)
    R_rect = np.stack([x, y, np.cross(x, y)])
    H_left = K_left @ R_rect @ np.linalg.inv(K_left)
    H_right = K_left @ R_rect @ R_right.T @ np.linalg.inv(K_right)
    return R_rect, H_left, H_right


def sfm_mvs_depth(
    images: dict[str, np.ndarray],
    K: dict[str, np.ndarray],
    m_lr: Matches,
    m_lb: Matches,
    c_lr: float,
    rng: np.random.Generator,
    matcher: StereoMatcher | None = None,
) -> np.ndarray:
    """Depth of the left view (H, W) float32, metres, z in the left camera, NaN = none.

    images: ``left``/``right``/``back`` (H, W) float32 grey; K: their true (3, 3)
    intrinsics. Raises PipelineError where SfM fails."""
    poses = colmap_poses(images, K, m_lr, m_lb, c_lr, rng)
    return depth_from_poses(images["left"], images["right"], K, poses, m_lr, matcher)


def depth_from_poses(
    left: np.ndarray,
    right: np.ndarray,
    K: dict[str, np.ndarray],
    poses: RigPoses,
    m_lr: Matches,
    matcher: StereoMatcher | None = None,
) -> np.ndarray:
    """The dense step: rectify with ``poses``, match, triangulate every left pixel.
    Returns (H, W) float32, metres, z in the left camera, NaN = none."""
    R_rect, H_l, H_r = calibrated_rectification(
        K["left"], K["right"], poses.R["right"], poses.C["right"]
    )
    pair = on_canvas(H_l, H_r, (left.shape[1], left.shape[0]), m_lr.left, m_lr.other)
    disparity = dense_disparity(left, right, pair, matcher)
    _, d = left_grid(disparity, pair.H_left, left.shape)
    # Rectified frame: the right centre is at (B, 0, 0), so z_rect = f B / disparity.
    f = K["left"][0, 0]
    baseline = float(np.linalg.norm(poses.C["right"]))
    with np.errstate(divide="ignore", invalid="ignore"):
        z_rect = f * baseline / (d.astype(np.float64) + pair.shift)
    h, w = left.shape
    v, u = np.mgrid[0:h, 0:w].astype(np.float64)
    rays_rect = np.stack([u, v, np.ones_like(u)], axis=-1) @ (R_rect @ np.linalg.inv(K["left"])).T
    # X_rect = rays_rect * z_rect / rays_rect_z; the left camera's z is R_rect[:, 2] . X_rect.
    with np.errstate(invalid="ignore"):
        z = (rays_rect @ R_rect[:, 2]) * z_rect / rays_rect[..., 2]
    return np.where(z > 0, z, np.nan).astype(np.float32)
