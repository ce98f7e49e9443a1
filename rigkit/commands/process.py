"""``rigkit process``: depth, previews and laser comparisons for capture sessions."""

from __future__ import annotations

import argparse
from pathlib import Path

EXAMPLE = """examples:
  rigkit process capture/example
  rigkit process capture/* --jobs 2
  rigkit process /mnt/capture/* --scheduler tcp://10.0.0.5:8786   # on a Dask cluster

for each session writes SESSION/results/ (depth.npy, sigma.npy, depth.json, depth.png
and left.png with the targets marked, sigma.png, comparisons.csv), replacing the previous
results as a whole, and appends one row per target to SESSION/comparisons.csv.
A session that fails is reported and the others go on; the exit code is 1 if any failed.
With --scheduler each session is a task on a Dask distributed cluster whose workers see
the sessions at the same paths (pip install 'rigkit[cluster]'; docs/sessions.md).
"""


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "process",
        help="process capture sessions: depth, previews, rangefinder comparisons",
        description="Run the depth pipeline on each session and compare the estimate "
        "with every laser-ranged target (docs/sessions.md).",
        epilog=EXAMPLE,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("sessions", type=Path, nargs="+", metavar="SESSION", help="session folders")
    p.add_argument("--jobs", type=int, help="sessions processed at once (default: as many "
                   "as cores and free memory allow)")
    p.add_argument("--force", action="store_true",
                   help="process despite an EXIF focal length that contradicts the rig")
    p.add_argument("--scheduler", metavar="tcp://HOST:PORT",
                   help="run each session as a task on this Dask distributed scheduler's "
                   "workers instead of local processes")
    p.add_argument("--quiet", action="store_true", help="no progress output")
    p.set_defaults(runner="rigkit.commands.process_run:run")
