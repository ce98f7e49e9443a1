"""Accuracy on the authors' elephant scene, rendered (../shared/data/elephant beside the
checkout, or
wherever ``--scene`` points: left/right/back.png, depth.npz, scene.json).

    python -m benchmarks.eval_elephant                       # estimate, then score
    python -m benchmarks.eval_elephant --depth out/el.npy    # score a saved estimate
    python -m benchmarks.eval_elephant --save out/el.npy     # estimate, keep it, score

It prints what ``rigkit eval`` prints for a synthetic scene (rigkit.synth.evaluate):

* under 1 %: the share of the *judged* pixels whose relative depth error is under 1 %,
  a missing estimate counted as a miss. A pixel is judged where it has ground truth
  and the right camera sees the same surface point: inside the right image and not
  hidden there. The scene has no right-view depth, so hiding is found with a z-buffer
  of the left view's own surface points splatted into the right image (a point more
  than ``OCCLUSION_TOLERANCE`` farther than the nearest one landing on the same right
  pixel is hidden), as ``visible_in_right`` compares against the right view's depth.
* false depth: the share of the background (ground truth NaN, nothing there) given a
  finite depth.
* bias: the median of (estimate - truth) / truth over judged pixels with an estimate.

The estimate runs as ``rigkit depth`` runs it (``estimate_depth`` with the default
settings, the focal length and baselines of scene.json, the images read by
``load_grey``).
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

from benchmarks.common import SHARED_DATA
from rigkit.imagefile.decode import load_grey
from rigkit.pipeline import RigGeometry, estimate_depth
from rigkit.synth.evaluate import OCCLUSION_TOLERANCE, depth_metrics

SCENE = SHARED_DATA / "elephant"


def judged_pixels(truth: np.ndarray, scene: dict) -> np.ndarray:
    """(H, W) bool: left pixels with ground truth whose surface point the right camera
    sees. truth: (H, W) float32, metres, z in the left camera, NaN = no surface; scene:
    scene.json (each camera's ``K``, ``R_cam_to_world``, ``center``)."""
    cams = scene["cameras"]
    h, w = truth.shape
    ys, xs = np.nonzero(np.isfinite(truth))
    z = truth[ys, xs].astype(np.float64)
    K_l, R_l, C_l = (np.asarray(cams["left"][k], np.float64) for k in
                     ("K", "R_cam_to_world", "center"))
    K_r, R_r, C_r = (np.asarray(cams["right"][k], np.float64) for k in
                     ("K", "R_cam_to_world", "center"))
    pix = np.stack([xs, ys, np.ones_like(xs)]).astype(np.float64)  # (3, N)
    X = R_l @ (np.linalg.solve(K_l, pix) * z) + C_l[:, None]  # world points (3, N)
    cam_r = R_r.T @ (X - C_r[:, None])
    uv = (K_r @ cam_r)[:2] / cam_r[2]
    zr = cam_r[2]
    ui, vi = np.rint(uv[0]).astype(np.int64), np.rint(uv[1]).astype(np.int64)
    inside = (ui >= 0) & (ui < w) & (vi >= 0) & (vi < h) & (zr > 0)
    flat = vi[inside] * w + ui[inside]
    nearest = np.full(h * w, np.inf)
    np.minimum.at(nearest, flat, zr[inside])  # the right view's z-buffer
    seen = np.zeros(len(z), bool)
    seen[inside] = zr[inside] <= nearest[flat] * (1 + OCCLUSION_TOLERANCE)
    out = np.zeros(truth.shape, bool)
    out[ys[seen], xs[seen]] = True
    return out


def estimate(scene_dir: Path, scene: dict) -> np.ndarray:
    """The left view's depth as ``rigkit depth`` gives it: (H, W) float32, metres."""
    left, right, back = (load_grey(scene_dir / f"{name}.png")
                         for name in ("left", "right", "back"))
    # One camera model for the three views (the same K): the rig says so, as a
    # profile's one_camera: true does.
    one_camera = all(k == scene["cameras"]["left"] for k in scene["cameras"].values())
    rig = RigGeometry(scene["f_px"], scene["C_lr"], scene["C_lb"], one_camera=one_camera)
    t0 = time.perf_counter()
    result = estimate_depth(left, right, back, rig)
    print(f"estimated in {time.perf_counter() - t0:.1f} s; "
          f"no-surface {100 * result.no_surface.mean():.1f} % of the frame, "
          f"views disagree {100 * result.disagree.mean():.2f} %")
    return result.depth


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--scene", type=Path, default=SCENE, help="the scene's folder")
    ap.add_argument("--depth", type=Path, help="score this (H, W) .npy instead of estimating")
    ap.add_argument("--save", type=Path, help="keep the estimate here (.npy)")
    args = ap.parse_args(argv)
    scene = json.loads((args.scene / "scene.json").read_text())
    truth = np.load(args.scene / "depth.npz")["depth"].astype(np.float32)
    depth = np.load(args.depth) if args.depth else estimate(args.scene, scene)
    if args.save:
        np.save(args.save, depth)
    judged = judged_pixels(truth, scene)
    m = depth_metrics(depth, truth, judged, "elephant")
    print(f"judged {m.judged_pixels} px ({100 * judged.mean():.1f} % of the frame), "
          f"density {100 * m.density:.2f} %")
    print(f"under 0.5/1/2/3 %: {100 * m.under_0_5:.2f} / {100 * m.under_1:.2f} / "
          f"{100 * m.under_2:.2f} / {100 * m.under_3:.2f} %")
    print(f"background given a depth (false depth): {100 * m.false_depth:.2f} %")
    print(f"median bias: {100 * m.median_bias:+.3f} %")
    return 0


if __name__ == "__main__":
    sys.exit(main())
