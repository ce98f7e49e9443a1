"""``rigkit synth``: render a synthetic three-view scene with ground truth."""

from __future__ import annotations

import argparse
from pathlib import Path

from rigkit.progress import Progress

EXAMPLE = """example:
  rigkit synth out/scene-7 --seed 7                      # paper protocol, 4608x3456, 6 deg, 300 m
  rigkit synth out/small --seed 1 --width 1152 --height 864
"""


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "synth",
        help="render a synthetic left/right/back scene with ground-truth depth",
        description="Render a random long-range scene seen by the three cameras, with "
        "exact ground-truth depth and poses (layout: docs/synthetic-scenes.md).",
        epilog=EXAMPLE,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("out_dir", type=Path, help="folder to write (created if missing)")
    p.add_argument("--seed", type=int, default=0, help="random seed: same seed, same scene")
    p.add_argument("--width", type=int, default=4608, help="image width, px")
    p.add_argument("--height", type=int, default=3456, help="image height, px")
    p.add_argument("--fov", type=float, default=6.0, help="horizontal field of view, degrees")
    p.add_argument("--distance", type=float, default=300.0, help="scene distance, m")
    p.add_argument("--baseline-lr", type=float, default=2.0, help="left-right baseline C_lr, m")
    p.add_argument("--baseline-lb", type=float, default=2.0, help="left-back distance C_lb, m")
    p.add_argument("--back-up", type=float, default=0.3, help="back camera raised by, m")
    p.add_argument("--back-side", type=float, default=0.0, help="back camera offset right, m")
    p.add_argument("--max-tilt", type=float, default=1.0, help="max x/y rotation, degrees")
    p.add_argument("--max-roll", type=float, default=5.0, help="max z rotation, degrees")
    p.add_argument("--max-pp-offset", type=float, default=30.0, help="principal point offset, px")
    p.add_argument("--relief", type=float, default=0.03, help="terrain depth range / distance")
    p.add_argument("--noise", type=float, default=1.5, help="read noise sigma, 8-bit DN")
    p.add_argument("--quiet", action="store_true", help="no progress output")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from rigkit.synth import SynthParams, generate_scene, write_scene

    params = SynthParams(
        width=args.width,
        height=args.height,
        hfov_deg=args.fov,
        distance_m=args.distance,
        baseline_lr_m=args.baseline_lr,
        baseline_lb_m=args.baseline_lb,
        back_up_m=args.back_up,
        back_side_m=args.back_side,
        max_tilt_deg=args.max_tilt,
        max_roll_deg=args.max_roll,
        max_pp_offset_px=args.max_pp_offset,
        relief=args.relief,
        noise_dn=args.noise,
    )
    scene = generate_scene(params, args.seed)
    timings = write_scene(scene, args.out_dir, Progress("synth", args.quiet))
    total = sum(timings.values())
    print(
        f"wrote {args.out_dir} ({params.width}x{params.height}, f={params.focal_px:.1f} px, "
        f"seed {args.seed}) in {total:.1f} s"
    )
    return 0
