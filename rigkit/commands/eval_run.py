"""Running ``rigkit eval`` (its arguments: :mod:`rigkit.commands.eval`)."""

from __future__ import annotations

import argparse


def run(args: argparse.Namespace) -> int:
    from rigkit.synth.evaluate import evaluate_scenes, format_table, goal_line, write_csv

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
