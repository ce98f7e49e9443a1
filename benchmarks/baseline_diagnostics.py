"""Why the Table 1 baselines fail: per scene, what each one got wrong in its geometry.

    python -m benchmarks.baseline_diagnostics out/table1/scenes/seed-*

For scenes rendered by ``rigkit experiments table1`` (ground-truth poses in scene.yaml):

* paper: row RMS (px) of its affine pseudo-rectification over the RANSAC inliers, and
  the rectified row error of the exact rotations at the image corners; the offset q
  and the number of pairs that voted;
* loop-zhang: distance (px) of the estimated and the true left epipole from the image
  centre (a 1/150 baseline puts the true one ~150 image widths away or at infinity);
* sfm-mvs: COLMAP's error in the right camera's rotation (deg, about x/y/z in the left
  frame) and in the back camera's centre (m).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

from rigkit.experiments.loop_zhang import fundamental_ransac
from rigkit.experiments.paper import PaperSettings, affine_rows_ransac, affine_warps
from rigkit.experiments.sfm import colmap_poses
from rigkit.geometry import Camera
from rigkit.imagefile.decode import load_grey
from rigkit.pipeline.features import match_views
from rigkit.synth import load_scene

VIEWS = ("left", "right", "back")


def _true_f(left: Camera, right: Camera) -> np.ndarray:
    R = right.R @ left.R.T
    t = right.R @ (left.C - right.C)
    tx = np.array([[0, -t[2], t[1]], [t[2], 0, -t[0]], [-t[1], t[0], 0]])
    return np.linalg.inv(right.K).T @ tx @ R @ np.linalg.inv(left.K)


def _epipole_distance(F: np.ndarray, centre: np.ndarray) -> float:
    e = np.linalg.svd(F)[2][-1]
    return float("inf") if abs(e[2]) < 1e-15 else float(np.linalg.norm(e[:2] / e[2] - centre))


def _small_angles_deg(R: np.ndarray) -> np.ndarray:
    """(x, y, z) rotation angles (deg) of a near-identity rotation."""
    return np.degrees([R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1]]) / 2


def diagnose(folder: Path) -> str:
    t = load_scene(folder)
    im = {v: load_grey(t.image_path(v)) for v in VIEWS}
    m_lr = match_views(im["left"], im["right"])
    m_lb = match_views(im["left"], im["back"])
    rng = np.random.default_rng(0)
    rows, inl = affine_rows_ransac(m_lr.left, m_lr.other, PaperSettings(), rng)
    H_l, H_r = affine_warps(rows)
    dy = (m_lr.left @ H_l[1, :2] + H_l[1, 2]) - (m_lr.other @ H_r[1, :2] + H_r[1, 2])
    row_rms = float(np.sqrt(np.mean(dy[inl] ** 2)))
    F, _ = fundamental_ransac(m_lr.left, m_lr.other, rng)
    c = np.array([(im["left"].shape[1] - 1) / 2, (im["left"].shape[0] - 1) / 2])
    e_est = _epipole_distance(F, c)
    e_true = _epipole_distance(_true_f(t.cameras["left"], t.cameras["right"]), c)
    K = {v: t.cameras[v].K for v in VIEWS}
    try:
        poses = colmap_poses(im, K, m_lr, m_lb, t.baseline_lr_m, rng)
        rot = _small_angles_deg(poses.R["right"].T @ t.cameras["right"].R)
        back = float(np.linalg.norm(poses.C["back"] - t.cameras["back"].C))
        sfm = f"rot err x {rot[0]:+.3f} y {rot[1]:+.3f} z {rot[2]:+.3f} deg, back {back:.2f} m"
    except Exception as exc:  # noqa: BLE001 - a diagnostic prints whatever went wrong
        sfm = f"failed: {exc}"
    return (
        f"{folder.name}: paper rows {row_rms:.2f} px ({int(inl.sum())}/{len(inl)} inliers); "
        f"L-Z epipole {e_est:.3g} px from centre (true {e_true:.3g}); sfm {sfm}"
    )


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    ap.add_argument("scenes", nargs="+", type=Path)
    for folder in ap.parse_args(argv).scenes:
        print(diagnose(folder), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
