"""``rigkit experiments``: rerun the paper's experiments (docs/experiments.md).

``table1`` compares four methods on synthetic scenes, ``bas-relief`` repeats the
two-view SfM simulation of sec. 5.1, ``stereo`` scores the stereo matcher on
Middlebury's Motorcycle pair.
"""

from __future__ import annotations

import argparse
import json
from dataclasses import asdict
from pathlib import Path

from rigkit.errors import InputError

_EPILOG = """\
examples:
  rigkit experiments table1 --scenes 40 --width 1152 --height 864 --out out/table1
  rigkit experiments bas-relief --runs 200 --out out/basrelief
  rigkit experiments stereo

What each experiment does and what was substituted: docs/experiments.md.
"""


def register(subparsers: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Add ``experiments`` with ``table1``, ``bas-relief`` and ``stereo``."""
    parser = subparsers.add_parser(
        "experiments",
        help="rerun the paper's experiments: Table 1 baselines, bas-relief, stereo",
        description="Reproduce the paper's experiments on our scenes, with our numbers "
        "next to the paper's.",
        epilog=_EPILOG,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    sub = parser.add_subparsers(dest="experiment", metavar="EXPERIMENT", required=True)
    t = sub.add_parser(
        "table1",
        help="rigkit, the paper's method, Loop-Zhang and SfM+MVS on the same synthetic scenes",
        description="Render N synthetic scenes (paper protocol; reused when already in "
        "OUT/scenes), run each method, and write OUT/table1.csv, OUT/table1_scenes.csv and "
        "OUT/table1.png. sfm-mvs needs pycolmap: pip install 'rigkit[experiments]'.",
        epilog="example:\n  rigkit experiments table1 --scenes 2 --width 1152 --height 864 "
        "--out out/t1",
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    t.add_argument("--scenes", type=int, required=True, help="number of scenes")
    t.add_argument("--seed", type=int, default=1001, help="first scene's seed (default 1001)")
    t.add_argument("--width", type=int, default=4608, help="image width, px (default 4608)")
    t.add_argument("--height", type=int, default=3456, help="image height, px (default 3456)")
    t.add_argument("--methods", default=",".join(_methods()),
                   help="comma-separated subset of %(default)s")
    t.add_argument("--out", type=Path, required=True, help="output folder")
    t.add_argument("--quiet", action="store_true", help="no progress display")
    t.set_defaults(func=run_table1)
    b = sub.add_parser(
        "bas-relief",
        help="two-view SfM on a distant Gaussian hill (paper sec. 5.1)",
        description="Repeat sec. 5.1's simulation RUNS times; write OUT/basrelief.csv "
        "(one line per run), OUT/basrelief.json (summary) and OUT/basrelief.png.",
    )
    b.add_argument("--runs", type=int, default=200, help="simulations (default 200)")
    b.add_argument("--seed", type=int, default=0, help="random seed (default 0)")
    b.add_argument("--noise", type=float, default=None,
                   help="pixel noise sigma per axis (default 2^-1/4 px: the paper's "
                   "covariance diag(1/sqrt 2))")
    b.add_argument("--out", type=Path, required=True, help="output folder")
    b.set_defaults(func=run_bas_relief)
    s = sub.add_parser(
        "stereo",
        help="the stereo matcher on Middlebury's Motorcycle pair (bad-1, bad-2)",
        description="Run rigkit's SGBM on the Motorcycle pair shipped with scikit-image "
        "and print bad-1/bad-2 over all ground-truth pixels and over estimated ones.",
    )
    s.add_argument("--json", action="store_true", help="print the scores as JSON")
    s.set_defaults(func=run_stereo)


def _methods() -> tuple[str, ...]:
    from rigkit.experiments.table1 import METHODS

    return METHODS


def _parse_methods(text: str) -> list[str]:
    known = _methods()
    methods = [m.strip() for m in text.split(",") if m.strip()]
    unknown = [m for m in methods if m not in known]
    if unknown or not methods:
        raise InputError(f"--methods: unknown {', '.join(unknown) or '(none given)'}; "
                         f"choose from {', '.join(known)}")
    if "sfm-mvs" in methods:
        try:
            import pycolmap  # noqa: F401
        except ImportError:
            raise InputError(
                "sfm-mvs needs pycolmap: pip install 'rigkit[experiments]' "
                "(or leave it out with --methods)"
            ) from None
    return methods


def run_table1(args: argparse.Namespace) -> int:
    from rigkit.core.progress import Progress
    from rigkit.experiments.table1 import run_table1 as run
    from rigkit.experiments.table1 import scene_dirs, table_text
    from rigkit.synth import SynthParams

    if args.scenes < 1:
        raise InputError(f"--scenes must be at least 1, got {args.scenes}")
    methods = _parse_methods(args.methods)
    params = SynthParams(width=args.width, height=args.height)
    params.validate()
    seeds = list(range(args.seed, args.seed + args.scenes))
    tasks = [d.name for d in scene_dirs(args.out, seeds, params)]
    with Progress("table1", tasks, quiet=args.quiet) as progress:
        rows = run(args.out, seeds, params, methods, progress.update)
    print(f"Table 1: {args.scenes} scenes at {args.width}x{args.height}, seeds "
          f"{seeds[0]}-{seeds[-1]}")
    print(table_text(rows))
    print(f"wrote {args.out / 'table1.csv'}, table1_scenes.csv, table1.png")
    return 0


def run_bas_relief(args: argparse.Namespace) -> int:
    import numpy as np

    from rigkit.core.files import write_bytes, write_text
    from rigkit.experiments.basrelief import BasReliefSetup, figure_png, run_many, runs_csv

    if args.runs < 1:
        raise InputError(f"--runs must be at least 1, got {args.runs}")
    if args.noise is not None and args.noise < 0:
        raise InputError(f"--noise must not be negative, got {args.noise}")
    setup = BasReliefSetup() if args.noise is None else BasReliefSetup(noise_sigma_px=args.noise)
    results, summary = run_many(setup, args.runs, np.random.default_rng(args.seed))
    args.out.mkdir(parents=True, exist_ok=True)
    write_text(args.out / "basrelief.csv", runs_csv(results))
    write_text(args.out / "basrelief.json", json.dumps(asdict(summary), indent=2) + "\n")
    write_bytes(args.out / "basrelief.png", figure_png(results))
    x, y, z = summary.rot_median_deg
    print(f"{summary.runs} runs, noise sigma {setup.noise_sigma_px:.3f} px per axis")
    print(f"|rotation error| median x {x:.4f}, y {y:.4f}, z {z:.4f} deg; "
          f"y mean {summary.rot_mean_deg[1]:.4f}, 95th pct {summary.rot_p95_deg[1]:.4f} deg "
          f"(paper, one run: 0.207 deg about y)")
    print(f"baseline direction error median {summary.t_median_deg:.2f} deg; "
          f"{100 * summary.flipped_share:.0f} % of runs put the right camera on the wrong side")
    print(f"median |relative depth error| of the points: {100 * summary.depth_error_median:.1f} %")
    print(f"wrote {args.out / 'basrelief.csv'}, basrelief.json, basrelief.png")
    return 0


def run_stereo(args: argparse.Namespace) -> int:
    from rigkit.experiments.middlebury import evaluate_motorcycle

    s = evaluate_motorcycle()
    if args.json:
        print(json.dumps(asdict(s), indent=2))
        return 0
    print(f"Motorcycle (Middlebury 2014, scikit-image), SGBM: {s.judged} pixels with "
          f"ground truth, {100 * s.density:.1f} % estimated")
    print(f"  all pixels:       bad-1 {100 * s.bad1_all:.2f} %  bad-2 {100 * s.bad2_all:.2f} %")
    print(f"  estimated pixels: bad-1 {100 * s.bad1_est:.2f} %  bad-2 {100 * s.bad2_est:.2f} %")
    return 0
