"""``rigkit report``: tables, statistics and plots of sessions' rangefinder comparisons."""

from __future__ import annotations

import argparse
from pathlib import Path

from rigkit.commands import output_folder

EXAMPLE = """example:
  rigkit report capture/field-1 capture/field-2 --out out/report
  rigkit report capture/field-1 --out out/field-1-history --all-runs
  rigkit report capture/field-1 --out out/paper --format png,svg,pdf

reads SESSION/comparisons.csv (written by rigkit process) of each session, by default
only the newest run, and writes into DIR: comparisons.csv (the rows reported),
report.txt (the text printed), estimate_vs_laser.png and error_vs_range.png (and .svg,
.pdf with --format), staged in a temporary folder and moved into place together.
error = estimate - laser (positive: the estimate is too far), in % of the laser range.
"""


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "report",
        help="tables, statistics and plots of depth estimates vs the laser rangefinder",
        description="Summarise the rangefinder comparisons logged by `rigkit process` in "
        "session folders: every comparison, error statistics overall and by laser range "
        "(docs/report.md), and two plots.",
        epilog=EXAMPLE,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument(
        "sessions",
        nargs="*",
        type=Path,
        metavar="SESSION",
        help="session folder holding comparisons.csv (one or more)",
    )
    p.add_argument(
        "--out", type=output_folder, required=True, metavar="DIR",
        help="folder to write the report into"
    )
    p.add_argument(
        "--all-runs",
        action="store_true",
        help="report every run in the logs, not only each session's newest",
    )
    p.add_argument(
        "--format",
        default="png",
        metavar="FORMATS",
        help="plot file formats, comma-separated, of png, svg, pdf (default png)",
    )
    p.set_defaults(runner="rigkit.commands.report_run:run")
