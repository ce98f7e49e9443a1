"""Running ``rigkit experiments`` (their arguments: :mod:`rigkit.commands.experiments`)."""

from __future__ import annotations

import argparse
import json
from dataclasses import asdict

from rigkit.errors import InputError


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

    from rigkit.core.outputs import check_outputs, write_outputs
    from rigkit.experiments.basrelief import BasReliefSetup, figure_png, run_many, runs_csv

    if args.runs < 1:
        raise InputError(f"--runs must be at least 1, got {args.runs}")
    if args.noise is not None and args.noise < 0:
        raise InputError(f"--noise must not be negative, got {args.noise}")
    setup = BasReliefSetup() if args.noise is None else BasReliefSetup(noise_sigma_px=args.noise)
    names = ("basrelief.csv", "basrelief.json", "basrelief.png")
    check_outputs(args.out, names, "--out", "experiments")
    results, summary = run_many(setup, args.runs, np.random.default_rng(args.seed))
    args.out.mkdir(parents=True, exist_ok=True)
    contents = (runs_csv(results), json.dumps(asdict(summary), indent=2) + "\n",
                figure_png(results))
    write_outputs(args.out, dict(zip(names, contents, strict=True)), "--out", "experiments")
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
