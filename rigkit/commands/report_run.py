"""Running ``rigkit report`` (its arguments: :mod:`rigkit.commands.report`)."""

from __future__ import annotations

import argparse
from pathlib import Path

from rigkit.capture.comparisons import csv_text
from rigkit.capture.session import check_outside
from rigkit.core.outputs import check_output_folder, check_outputs, write_outputs
from rigkit.core.tables import warn
from rigkit.errors import InputError
from rigkit.reporting.plots import FORMATS, plot_error_vs_range, plot_estimate_vs_laser, render
from rigkit.reporting.scale import calibration_rows, session_scale_note
from rigkit.reporting.summary import collect, format_text, summarize

#: The plots, by file stem; each is written in every --format.
PLOTS = ("estimate_vs_laser", "error_vs_range")


def _formats(text: str) -> list[str]:
    formats = list(dict.fromkeys(f.strip().lower() for f in text.split(",") if f.strip()))
    unknown = [f for f in formats if f not in FORMATS]
    if unknown or not formats:
        raise InputError(f"--format {text}: expected one or more of {', '.join(FORMATS)}")
    return formats


def run(args: argparse.Namespace) -> int:
    if not args.sessions:
        raise InputError("no session folders given (e.g. rigkit report capture/field-1 --out DIR)")
    formats = _formats(args.format)
    _check_out(args.out, args.sessions, formats)
    torn: list[str] = []
    rows = collect(args.sessions, all_runs=args.all_runs, torn=torn)
    warn(torn)
    if not rows:
        raise InputError(f"no comparisons in {', '.join(map(str, args.sessions))} (an empty "
                         "log, or every row damaged): nothing to report; rigkit process a "
                         "session with laser targets first")
    calibrated = calibration_rows(args.sessions)
    counted = [r for r in rows if (r.session, r.target) not in calibrated]
    text = format_text(rows, summarize(counted), calibrated)
    notes = [(path, session_scale_note(path)) for path in dict.fromkeys(args.sessions)]
    text += "".join(f"scale of {path}: {note}\n" for path, note in notes if note)
    files: dict[str, str | bytes] = {"comparisons.csv": csv_text(rows), "report.txt": text}
    for stem, plot in zip(PLOTS, (plot_estimate_vs_laser, plot_error_vs_range), strict=True):
        figure = plot(rows)
        for fmt in formats:
            files[f"{stem}.{fmt}"] = render(figure, fmt)
    _write_all(args.out, files)
    print(text, end="")
    print(f"wrote {', '.join(str(args.out / name) for name in files)}")
    return 0


def _names(formats: list[str]) -> list[str]:
    """The files a report writes, with its plots in ``formats``."""
    return ["comparisons.csv", "report.txt", *(f"{stem}.{fmt}" for stem in PLOTS
                                               for fmt in formats)]


def _check_out(out: Path, sessions: list[Path], formats: list[str]) -> None:
    """--out never inside a session it reports (its comparisons.csv would replace the
    session's log), and no file it writes one rigkit did not write
    (:mod:`rigkit.core.outputs`), said before the work."""
    check_output_folder(out, "--out")
    check_outside(out / "comparisons.csv", sessions, f"--out {out}")
    check_outputs(out, _names(formats), "--out", "report")


def _write_all(out: Path, files: dict[str, str | bytes]) -> None:
    """All report files at once (:func:`rigkit.core.outputs.write_outputs`); a folder
    that cannot be created or written is a one-line error naming --out."""
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise InputError(f"--out {out}: cannot create the folder ({exc.strerror})") from None
    try:
        write_outputs(out, files, "--out", "report")
    except OSError as exc:
        raise InputError(f"--out {out}: cannot write the report ({exc.strerror})") from None
