"""The ``rigkit`` command line: ``rigkit <command> --help`` for each command."""

from __future__ import annotations

import argparse
import importlib
import sys
from collections.abc import Sequence

from rigkit import __version__
from rigkit.errors import RigkitError

# Subcommand modules under rigkit.commands, in the order --help lists them.
COMMANDS: tuple[str, ...] = (
    "depth",
    "synth",
    "eval",
    "rig",
    "rangefinder",
    "session",
    "process",
    "report",
    "export",
    "field",
    "experiments",
)


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="rigkit",
        description="Dense metric depth at 200-500 m from a left, right and back telephoto camera.",
        epilog="Run 'rigkit COMMAND --help' for a command's options and an example.",
    )
    parser.add_argument("--version", action="version", version=f"rigkit {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)
    for name in COMMANDS:
        importlib.import_module(f"rigkit.commands.{name}").register(sub)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        code: int = args.func(args)
    except RigkitError as exc:
        print(f"rigkit {args.command}: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"rigkit {args.command}: interrupted", file=sys.stderr)
        return 130
    except BrokenPipeError:
        # Output piped into a reader that stopped (e.g. `| head`): not an error.
        sys.stderr.close()
        return 0
    return code


if __name__ == "__main__":
    sys.exit(main())
