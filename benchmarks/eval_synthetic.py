"""Accuracy on the paper's synthetic protocol: render seeds (if missing), estimate depth,
print the Table-1-style evaluation.

    python benchmarks/eval_synthetic.py --seeds 101-120 --work out/eval20
    python benchmarks/eval_synthetic.py --seeds 1-3 --width 1152 --height 864 --work out/small

Seeds 101-120 were never used while developing the pipeline (development used 1-5).
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

from rigkit.errors import RigkitError
from rigkit.pipeline import RigGeometry, estimate_depth
from rigkit.pipeline.images import load_grey
from rigkit.synth import SynthParams, generate_scene, load_scene, write_scene
from rigkit.synth.evaluate import evaluate_scenes, format_table, write_csv


def seed_list(text: str) -> list[int]:
    lo, _, hi = text.partition("-")
    return list(range(int(lo), int(hi or lo) + 1))


def main() -> int:
    ap = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    ap.add_argument("--seeds", default="101-120")
    ap.add_argument("--width", type=int, default=4608)
    ap.add_argument("--height", type=int, default=3456)
    ap.add_argument("--work", type=Path, default=Path("out/eval"))
    args = ap.parse_args()
    scenes, depth_dir = args.work / "scenes", args.work / "depth"
    depth_dir.mkdir(parents=True, exist_ok=True)
    dirs = []
    for seed in seed_list(args.seeds):
        d = scenes / f"seed-{seed}"
        dirs.append(d)
        if not (d / "scene.yaml").is_file():
            write_scene(generate_scene(SynthParams(width=args.width, height=args.height), seed), d)
        truth = load_scene(d)
        rig = RigGeometry(truth.focal_px, truth.baseline_lr_m, truth.baseline_lb_m)
        imgs = [load_grey(truth.image_path(v)) for v in ("left", "right", "back")]
        t0 = time.perf_counter()
        try:
            res = estimate_depth(*imgs, rig)
        except RigkitError as exc:
            print(f"seed {seed}: FAILED: {exc}", file=sys.stderr)
            (depth_dir / f"{d.name}.npy").unlink(missing_ok=True)
            continue
        np.save(depth_dir / f"{d.name}.npy", res.depth)
        print(
            f"seed {seed}: offset {res.ambiguity.offset_px:.2f} +- "
            f"{res.ambiguity.offset_sigma_px:.2f} px, {time.perf_counter() - t0:.1f} s",
            file=sys.stderr,
        )
    rows = evaluate_scenes(dirs, depth_dir)
    print(format_table(rows))
    write_csv(rows, args.work / "eval.csv")
    return 1 if any(m.failed for m in rows) else 0


if __name__ == "__main__":
    sys.exit(main())
