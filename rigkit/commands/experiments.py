"""``rigkit experiments``: rerun the paper's experiments (docs/experiments.md).

``table1`` compares four methods on synthetic scenes, ``bas-relief`` repeats the
two-view SfM simulation of sec. 5.1, ``stereo`` scores the stereo matcher on
Middlebury's Motorcycle pair.
"""

from __future__ import annotations

import argparse

from rigkit.commands import finite, output_folder
from rigkit.experiments.defaults import METHODS

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
    t.add_argument("--methods", default=",".join(METHODS),
                   help="comma-separated subset of %(default)s")
    t.add_argument("--out", type=output_folder, required=True, help="output folder")
    t.add_argument("--quiet", action="store_true", help="no progress display")
    t.set_defaults(runner="rigkit.commands.experiments_run:run_table1")
    b = sub.add_parser(
        "bas-relief",
        help="two-view SfM on a distant Gaussian hill (paper sec. 5.1)",
        description="Repeat sec. 5.1's simulation RUNS times; write OUT/basrelief.csv "
        "(one line per run), OUT/basrelief.json (summary) and OUT/basrelief.png.",
    )
    b.add_argument("--runs", type=int, default=200, help="simulations (default 200)")
    b.add_argument("--seed", type=int, default=0, help="random seed (default 0)")
    b.add_argument("--noise", type=finite, default=None,
                   help="pixel noise sigma per axis (default 2^-1/4 px: the paper's "
                   "covariance diag(1/sqrt 2))")
    b.add_argument("--out", type=output_folder, required=True, help="output folder")
    b.set_defaults(runner="rigkit.commands.experiments_run:run_bas_relief")
    s = sub.add_parser(
        "stereo",
        help="the stereo matcher on Middlebury's Motorcycle pair (bad-1, bad-2)",
        description="Run rigkit's SGBM on the Motorcycle pair shipped with scikit-image "
        "and print bad-1/bad-2 over all ground-truth pixels and over estimated ones.",
    )
    s.add_argument("--json", action="store_true", help="print the scores as JSON")
    s.set_defaults(runner="rigkit.commands.experiments_run:run_stereo")
