"""Where a scene's disparity-offset error comes from: re-fit the offset with parts of
the measured data replaced by the truth.

    python -m benchmarks.offset_sources out/field20/scenes/seed-2*

For rendered scenes (``rigkit synth``, ground truth in the folder), per scene:

* ``error``: the pipeline's offset error (px): the median over judged pixels of
  f C_lr (1/z_est - 1/z_true), with the sign of the offset;
* ``back matches``: what the back-view matches add, the offset fitted on the measured
  positions less the offset fitted on exact ones (the true point behind each left
  corner, projected by the true back camera);
* ``shimmer only``: the same, with exact positions moved by what the two frames'
  shimmer fields predict there, ``J s_left(p) - s_back(q)`` (the renderer's fields
  are drawn again from the scene's seed); ``tracker only``: the measured positions
  less that prediction. If ``shimmer only`` is ``back matches``, the tracker follows
  the shimmer faithfully and the error is the shimmer's own;
* ``model``: ``error`` less ``back matches``, what remains with exact back positions
  (the principal points, the disparity at the matches);
* ``pp term``: the principal-point part of the reported sigma, and ``sigma``: all of it.

Single frames only (frame 0 of a burst).
"""

from __future__ import annotations

import argparse
import sys
from dataclasses import replace
from pathlib import Path

import cv2
import numpy as np

from rigkit.errors import RigkitError
from rigkit.imagefile.decode import load_grey
from rigkit.pipeline import RigGeometry, estimate_depth
from rigkit.pipeline.ambiguity import remove_ambiguity
from rigkit.pipeline.features import match_views
from rigkit.synth import SceneTruth, load_scene
from rigkit.synth.evaluate import offset_error_px
from rigkit.synth.shimmer import displacement_field

VIEWS = ("left", "right", "back")


def _sample(field: np.ndarray, pts: np.ndarray) -> np.ndarray:
    m = pts.astype(np.float32).reshape(-1, 1, 2)
    return cv2.remap(field, m[..., 0], m[..., 1], cv2.INTER_LINEAR, borderValue=np.nan).ravel()


def _shimmer(truth: SceneTruth, view: str, shape: tuple[int, int], pts: np.ndarray) -> np.ndarray:
    """(N, 2) px: the renderer's shimmer displacement of ``view``'s frame 0 at ``pts``
    (zero where the scene has none); drawn as :func:`rigkit.synth.render.expose` does."""
    p = truth.params
    if not p.shimmer_px:
        return np.zeros((len(pts), 2))
    rng = np.random.default_rng([truth.seed, sorted(VIEWS).index(view), 0])
    dx, dy = displacement_field(shape, p.shimmer_px, p.shimmer_spectrum, p.shimmer_corr_px,
                                p.shimmer_outer_px, rng)
    return np.stack([_sample(dx, pts), _sample(dy, pts)], axis=1)


def analyse(scene_dir: Path) -> dict[str, float]:
    truth = load_scene(scene_dir)
    images = {v: load_grey(truth.image_path(v)) for v in VIEWS}
    rig = RigGeometry(truth.focal_px, truth.baseline_lr_m, truth.baseline_lb_m)
    result = estimate_depth(images["left"], images["right"], images["back"], rig)
    m = match_views(images["left"], images["back"], "left/back")
    rect = result.rectification
    cams = truth.cameras
    z = _sample(truth.depth("left"), m.left)
    X = cams["left"].C + z[:, None] * cams["left"].rays(m.left[:, 0], m.left[:, 1])
    back_true = cams["back"].project(X)[0]
    ok = np.isfinite(back_true).all(axis=1)
    shape = images["left"].shape
    predicted = (_shimmer(truth, "left", shape, m.left) @ m.affine[:, :2].T
                 - _shimmer(truth, "back", shape, back_true))
    ok &= np.isfinite(predicted).all(axis=1)
    m = replace(m, left=m.left[ok], other=m.other[ok])
    back_true, predicted = back_true[ok], predicted[ok]

    def offset(other: np.ndarray) -> float:
        amb = remove_ambiguity(replace(m, other=other), result.disparity,
                               result.disparity_scale, rect, rig, result.settings)
        return amb.offset_px

    error = -offset_error_px(truth, result.depth, rig.focal_px)
    ref = offset(back_true)
    matches = offset(m.other) - ref
    return {
        "error": error,
        "back matches": matches,
        "shimmer only": offset(back_true + predicted) - ref,
        "tracker only": offset(m.other - predicted) - ref,
        "model": error - matches,
        "pp term": result.ambiguity.principal_point_sigma_px,
        "sigma": result.ambiguity.offset_sigma_px,
    }


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("scenes", nargs="+", type=Path)
    args = ap.parse_args(argv)
    cols = ("error", "back matches", "shimmer only", "tracker only", "model", "pp term",
            "sigma")
    print(f"{'scene':10s}" + "".join(f"{c:>14s}" for c in cols) + "   (offset, px)")
    rows = []
    for scene in args.scenes:
        try:
            row = analyse(scene)
        except RigkitError as exc:
            print(f"{scene.name}: {exc}", file=sys.stderr)
            continue
        rows.append([row[c] for c in cols])
        print(f"{scene.name:10s}" + "".join(f"{row[c]:+14.2f}" for c in cols), flush=True)
    if rows:
        rms = np.sqrt(np.mean(np.square(rows), axis=0))
        print(f"{'RMS':10s}" + "".join(f"{v:14.2f}" for v in rms))
    return 0


if __name__ == "__main__":
    sys.exit(main())
