"""``rigkit report``: tables, statistics and plots of sessions' rangefinder comparisons."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    import numpy as np

EXAMPLE = """example:
  rigkit report capture/field-1 capture/field-2 --out out/report
  rigkit report capture/field-1 --out out/field-1-history --all-runs

reads SESSION/comparisons.csv (written by rigkit process) of each session, by default
only the newest run, and writes into DIR: comparisons.csv (the rows reported),
report.txt (the text printed), estimate_vs_laser.png and error_vs_range.png, staged in a
temporary folder and moved into place together.
error = estimate - laser (positive: the estimate is too far), in % of the laser range.
"""

#: The files written into --out, in the order they are listed.
OUTPUTS = ("comparisons.csv", "report.txt", "estimate_vs_laser.png", "error_vs_range.png")


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
        "--out", type=Path, required=True, metavar="DIR", help="folder to write the report into"
    )
    p.add_argument(
        "--all-runs",
        action="store_true",
        help="report every run in the logs, not only each session's newest",
    )
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from rigkit.capture.comparisons import csv_text
    from rigkit.errors import InputError
    from rigkit.report import (
        collect,
        format_text,
        plot_error_vs_range,
        plot_estimate_vs_laser,
        summarize,
    )

    if not args.sessions:
        raise InputError("no session folders given (e.g. rigkit report capture/field-1 --out DIR)")
    _check_out(args.out, args.sessions)
    rows = collect(args.sessions, all_runs=args.all_runs)
    text = format_text(rows, summarize(rows))
    files: dict[str, str | np.ndarray] = {
        "comparisons.csv": csv_text(rows),
        "report.txt": text,
        "estimate_vs_laser.png": plot_estimate_vs_laser(rows),
        "error_vs_range.png": plot_error_vs_range(rows),
    }
    _write_all(args.out, files)
    print(text, end="")
    print(f"wrote {', '.join(str(args.out / name) for name in OUTPUTS)}")
    return 0


def _check_out(out: Path, sessions: list[Path]) -> None:
    """--out must be a folder (or not exist yet) and never a session folder: its
    comparisons.csv would replace the session's log."""
    from rigkit.errors import InputError

    if out.exists() and not out.is_dir():
        raise InputError(f"--out {out}: exists and is not a folder")
    target = out.resolve()
    for session in sessions:
        if session.resolve() == target:
            raise InputError(f"--out {out}: is a session folder (its log would be replaced)")


def _write_all(out: Path, files: dict[str, str | np.ndarray]) -> None:
    """All report files at once (:func:`rigkit.core.files.write_together`); a folder that
    cannot be created or written is a one-line error naming --out."""
    from rigkit.core.files import write_together
    from rigkit.errors import InputError

    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise InputError(f"--out {out}: cannot create the folder ({exc.strerror})") from None
    try:
        write_together(out, files)
    except OSError as exc:
        raise InputError(f"--out {out}: cannot write the report ({exc.strerror})") from None
