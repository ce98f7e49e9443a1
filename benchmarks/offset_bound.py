"""How close the frames taken at each position can come to the field bar on the median
depth bias: the pipeline's offset error against the Cramér–Rao bound under the scene's
shimmer.

    python -m benchmarks.offset_bound out/field20/scenes/seed-2*

Per rendered scene (``rigkit synth`` with heat shimmer of the gaussian or vonkarman
spectrum; a burst scene is read as ``rigkit depth`` reads one, its frames stacked),
px of disparity offset (rigkit.synth.bound defines the two figures):

* ``error``: the pipeline's offset error (median over judged pixels of
  f C_lr (1/z_est - 1/z_true)); ``reported``: the standard error it reports;
* ``estimator``: the spread the shimmer gives the pipeline's least-squares offset on
  its own matches; ``surface``: on every point of the surface instead (a grid);
  ``bound``: the smallest spread any estimator can have, using every point of the
  surface and the shimmer's exact covariance (averaged over a burst's frames);
* ``bar``: the field bar, |median depth bias| <= 0.3 %, as px of offset (0.3 % of the
  median true disparity f C_lr / z); ``P(bound)``: the chance that an offset error of
  spread ``bound`` stays within the bar.

``--corr-px C`` computes the figures for gaussian shimmer of another correlation
length on the same scenes (the error and the reported sigma stay the rendered
shimmer's).

The summary gives how many scenes meet the bar, how many are expected to with the
pipeline's estimator and with the best one, and the chance that all of them do.
"""

from __future__ import annotations

import argparse
import math
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np

from rigkit.capture.frames import frame_files, load_capture
from rigkit.core.tables import render_table
from rigkit.errors import RigkitError
from rigkit.imagefile.decode import load_grey
from rigkit.pipeline import RigGeometry, estimate_depth
from rigkit.pipeline.features import match_views
from rigkit.synth import load_scene
from rigkit.synth.bound import TRACKER_PX, offset_bound
from rigkit.synth.evaluate import offset_error_px, visible_in_right

BIAS_BAR = 0.003  # the field issue's |median depth bias|


def within(bar: float, sigma: float) -> float:
    """P(|e| <= bar) for a zero-mean normal error e of standard deviation ``sigma``."""
    return math.erf(bar / (sigma * math.sqrt(2)))


def analyse(
    scene_dir: Path, step_px: float | None, corr_px: float | None, tracker_px: float
) -> dict[str, float]:
    truth = load_scene(scene_dir)
    if corr_px is not None:  # the same scene under shimmer of another correlation length
        truth = replace(truth, params=replace(truth.params, shimmer_corr_px=corr_px))
    views = ("left", "right", "back")
    if truth.params.burst > 1:  # stacked as rigkit depth stacks them
        left, right, back = load_capture(
            frame_files({v: truth.frame_paths(v) for v in views})).images
    else:
        left, right, back = (load_grey(truth.image_path(v)) for v in views)
    rig = RigGeometry(truth.focal_px, truth.baseline_lr_m, truth.baseline_lb_m)
    result = estimate_depth(left, right, back, rig)
    matches = match_views(left, back, "left/back")
    bound = offset_bound(truth, result, matches.left, step_px, tracker_px)
    z = truth.depth("left")[visible_in_right(truth)]
    bar = BIAS_BAR * rig.focal_px * rig.baseline_lr_m / float(np.median(z))
    return {
        "error": offset_error_px(truth, result.depth, rig.focal_px),
        "reported": result.ambiguity.offset_sigma_px,
        "estimator": bound.estimator_px,
        "surface": bound.surface_px,
        "bound": bound.bound_px,
        "bar": bar,
        "P(bound)": within(bar, bound.bound_px),
        "points": bound.grid_points,
    }


def summary(rows: list[dict[str, float]]) -> list[str]:
    met = sum(abs(r["error"]) <= r["bar"] for r in rows)
    lines = [f"scenes within the bar: {met} of {len(rows)}"]
    for name in ("estimator", "surface", "bound"):
        p = [within(r["bar"], r[name]) for r in rows]
        lines.append(
            f"expected within it with the {name}'s spread: {sum(p):.1f} of {len(rows)}; "
            f"all of them: {100 * math.prod(p):.2g} %"
        )
    return lines


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("scenes", nargs="+", type=Path)
    ap.add_argument("--step-px", type=float, default=None,
                    help="the dense grid's spacing (default: 0.7 correlation lengths of "
                    "gaussian shimmer, 1/32 of the outer scale of vonkarman shimmer)")
    ap.add_argument("--tracker-px", type=float, default=TRACKER_PX,
                    help=f"the tracker's own error per axis (default {TRACKER_PX:g})")
    ap.add_argument("--corr-px", type=float, default=None,
                    help="bound under shimmer of this correlation length instead of the "
                    "scene's (the pipeline's error is still the rendered shimmer's)")
    args = ap.parse_args(argv)
    cols = ("error", "reported", "estimator", "surface", "bound", "bar", "P(bound)")
    rows, names = [], []
    for scene in args.scenes:
        try:
            row = analyse(scene, args.step_px, args.corr_px, args.tracker_px)
        except RigkitError as exc:
            print(f"{scene.name}: {exc}", file=sys.stderr)
            continue
        rows.append(row)
        names.append(scene.name)
        print(f"{scene.name}: " + ", ".join(f"{c} {row[c]:+.3f}" for c in cols)
              + f" ({row['points']:.0f} grid points)", file=sys.stderr, flush=True)
    if not rows:
        return 1
    table: list[list[str] | None] = [
        [n] + [f"{r[c]:+.2f}" for c in cols[:-1]] + [f"{r['P(bound)']:.2f}"]
        for n, r in zip(names, rows, strict=True)]
    rms = [f"{math.sqrt(np.mean([r[c] ** 2 for r in rows])):.2f}" for c in cols[:-1]]
    table += [None, ["RMS", *rms, ""]]
    print("px of disparity offset; P(bound): the chance of the bar at the bound")
    print(render_table(("scene", *cols), table, left=(0,)))
    print("\n".join(summary(rows)))
    return 0


if __name__ == "__main__":
    sys.exit(main())
