"""``rigkit eval``: score depth estimates against synthetic ground truth."""

from __future__ import annotations

import argparse
from pathlib import Path

from rigkit.commands import output_file

EXAMPLE = """example:
  rigkit eval out/scene-1 out/scene-2 --depth-dir out/depth --csv out/eval.csv
  (the estimate for out/scene-1 is out/depth/scene-1.npy, out/depth/scene-1-depth.npy
   or out/depth/scene-1/depth.npy)
  rigkit eval capture/example
  (a processed synthetic session: its own results/depth.npy)
"""


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "eval",
        help="score depth maps against ground truth (the paper's Table 1 metric)",
        description="Fraction of left pixels (seen by the right camera) whose relative depth "
        "error is under 0.5/1/2/3 %, density and median bias. A missing estimate is a failure. "
        "Where the scene has movers or cloud shadows (ground_truth/moved_left.npy), also the "
        "static pixels' share under 1 % and bias, and what the moved pixels were given.",
        epilog=EXAMPLE,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("scenes", nargs="+", type=Path, help="scene folders written by rigkit synth")
    p.add_argument("--depth-dir", type=Path,
                   help="folder of depth estimates (default: each session's results/)")
    p.add_argument("--csv", type=output_file, help="also write the table as CSV here")
    p.add_argument("--goal", action="store_true",
                   help="end with one line per scene saying whether it meets the goal "
                   "(>= 95 %% of pixels under 1 %%, |bias| <= 0.3 %%, every laser target "
                   "within 1 %%); exit 1 where one does not")
    p.set_defaults(runner="rigkit.commands.eval_run:run")
