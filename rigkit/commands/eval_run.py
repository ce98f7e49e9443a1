"""Running ``rigkit eval`` (its arguments: :mod:`rigkit.commands.eval`)."""

from __future__ import annotations

import argparse

from rigkit.core.files import check_not_inputs
from rigkit.errors import InputError
from rigkit.synth.evaluate import (
    evaluate_scenes,
    files_read,
    format_table,
    goal_line,
    write_csv,
)


def run(args: argparse.Namespace) -> int:
    if args.csv:
        if args.csv.suffix.lower() != ".csv":
            raise InputError(f"--csv {args.csv}: expected a .csv file name")
        check_not_inputs([args.csv], files_read(args.scenes, args.depth_dir), f"--csv {args.csv}")
    rows = evaluate_scenes(args.scenes, args.depth_dir)
    print(format_table(rows))
    if args.csv:
        write_csv(rows, args.csv)
        print(f"wrote {args.csv}")
    failed = any(m.failed for m in rows)
    if args.goal:
        for m, scene in zip(rows, args.scenes, strict=True):
            met, line = goal_line(m, scene)
            print(line)
            failed |= not met
    return 1 if failed else 0
