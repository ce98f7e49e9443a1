"""Speed and peak memory of the depth pipeline, end to end and per stage, at 1/4, 1/2
and full 4608x3456 resolution (one synthetic triple each, rendered once and cached),
and side by side the time of a plain reading of the paper's method on the same images
(rigkit's matcher, then :func:`rigkit.experiments.paper.paper_depth`).

    python -m benchmarks.bench_depth [--work out/bench] [--sizes 1152,2304,4608] [--burst 5]
                                     [--default-memory]

Each size runs in a fresh process so that peak memory (max RSS) is its own; the
paper's method runs after rigkit in that process (its peak is not reported). With
``--burst N`` every position is a burst of N frames, read as ``rigkit depth`` reads
one (:func:`rigkit.capture.frames.load_capture`: decoded, aligned, median-stacked);
``load`` then includes the stacking, and the paper's method runs on the stacked triple.
Memory for large arrays is set up as the ``rigkit`` command sets it up
(:func:`rigkit.core.memory.tune_for_images`) unless ``--default-memory`` is given.
"""

from __future__ import annotations

import argparse
import json
import resource
import sys
import time
from pathlib import Path

from benchmarks.common import OUT, run_script


def run_one(scene: Path, tune: bool) -> dict:
    from rigkit.core.memory import tune_for_images
    from rigkit.imagefile.decode import load_grey
    from rigkit.pipeline import RigGeometry, estimate_depth
    from rigkit.synth import load_scene

    if tune:  # as the rigkit command does
        tune_for_images()
    truth = load_scene(scene)
    rig = RigGeometry(truth.focal_px, truth.baseline_lr_m, truth.baseline_lb_m)
    views = ("left", "right", "back")
    t0 = time.perf_counter()
    if truth.params.burst > 1:
        from rigkit.capture.frames import frame_files, load_capture

        bursts = frame_files({v: truth.frame_paths(v) for v in views})
        imgs = list(load_capture(bursts).images)
    else:
        imgs = [load_grey(truth.image_path(v)) for v in views]
    t_load = time.perf_counter() - t0
    left, right, back = imgs
    res = estimate_depth(left, right, back, rig)
    total = time.perf_counter() - t0
    peak_mb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    return {
        "load": round(t_load, 2),
        "lens": 0.0,
        **res.timings_s,
        "total": round(total, 2),
        "peak_mb": round(peak_mb),
        "paper": round(t_load + paper_seconds(imgs, truth), 2),
    }


def paper_seconds(imgs: list, truth) -> float:
    """Seconds the paper's method takes on the loaded triple (matching included)."""
    import numpy as np

    from rigkit.experiments.paper import paper_depth
    from rigkit.pipeline.features import match_views

    left, right, back = imgs
    t0 = time.perf_counter()
    m_lr = match_views(left, right, "left/right")
    m_lb = match_views(left, back, "left/back")
    paper_depth(left, right, m_lr, m_lb, truth.focal_px, truth.baseline_lr_m,
                truth.baseline_lb_m, np.random.default_rng(0))
    return time.perf_counter() - t0


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    ap.add_argument("--work", type=Path, default=OUT / "bench")
    ap.add_argument("--sizes", default="1152,2304,4608")
    ap.add_argument("--burst", type=int, default=1, help="frames per position (default 1)")
    ap.add_argument("--default-memory", action="store_true",
                    help="leave the C allocator's and NumPy's defaults for large arrays, "
                    "to see what rigkit.core.memory saves")
    ap.add_argument("--one", type=Path, help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.one:
        print(json.dumps(run_one(args.one, tune=not args.default_memory)))
        return 0
    from rigkit.synth import SynthParams, generate_scene, write_scene

    print(
        f"{'size':>11} {'pixels':>7} {'load':>5} {'match':>6} {'lens':>5} {'rect':>5} "
        f"{'stereo':>6} {'ambig':>6} {'agree':>6} {'depth':>6} {'total s':>7} {'peak MB':>7} "
        f"{'paper s':>7} {'ratio':>5}"
    )
    for w in (int(s) for s in args.sizes.split(",")):
        h = w * 3 // 4
        scene = args.work / (f"bench-{w}" if args.burst == 1 else f"bench-{w}-burst{args.burst}")
        if not (scene / "scene.yaml").is_file():
            params = SynthParams(width=w, height=h, burst=args.burst)
            write_scene(generate_scene(params, seed=1), scene)
        printed = run_script("bench_depth", "--one", str(scene.resolve()),
                             *(["--default-memory"] if args.default_memory else []))
        r = json.loads(printed.strip().splitlines()[-1])
        print(
            f"{w:>5}x{h:<5} {w * h / 1e6:6.1f}M {r['load']:5.2f} {r['matching']:6.2f} "
            f"{r['lens']:5.2f} {r['rectification']:5.2f} {r['stereo']:6.2f} "
            f"{r['ambiguity']:6.2f} {r.get('agreement', 0.0):6.2f} {r['depth']:6.2f} "
            f"{r['total']:7.2f} {r['peak_mb']:7d} "
            f"{r['paper']:7.2f} {r['total'] / r['paper']:5.2f}"
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
