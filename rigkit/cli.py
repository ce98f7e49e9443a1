"""The ``rigkit`` command line: ``rigkit <command> --help`` for each command."""

from __future__ import annotations

import argparse
import contextlib
import importlib
import logging
import sys
import warnings
from collections.abc import Callable, Iterator, Sequence
from typing import NoReturn

from rigkit import __version__
from rigkit.core.memory import tune_for_images
from rigkit.core.signals import Terminated
from rigkit.errors import RigkitError, environment_message

# Subcommand modules under rigkit.commands, in the order --help lists them. Each holds
# only its arguments; what runs a command is imported when it runs (_runner).
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


class _Parser(argparse.ArgumentParser):
    """argparse's parser, whose mistakes are one line, as every other bad input's: the
    command, what is wrong (names shown, never obeyed: :func:`_shown`) and where its
    options are listed. argparse's own printed the whole usage first (4-21 lines)."""

    def error(self, message: str) -> NoReturn:
        self.exit(2, f"{self.prog}: error: {_shown(message)} (options: {self.prog} "
                     "--help)\n")


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(
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
    _printable_names()
    try:  # Ctrl-C while the commands' modules load is an interruption like any other
        parser = build_parser()
    except KeyboardInterrupt as exc:
        return _interrupted("rigkit", exc)
    args = parser.parse_args(argv)
    tune_for_images()  # freed image-sized arrays reused, no huge-page stalls: ~1.4 s of a triple
    try:
        with _quiet_libraries():
            _check_outputs(parser, args)
            code: int = _runner(args.runner)(args)
    except RigkitError as exc:
        print(f"rigkit {args.command}: error: {_shown(str(exc))}", file=sys.stderr)
        return 2
    except KeyboardInterrupt as exc:
        return _interrupted(f"rigkit {args.command}", exc)
    except BrokenPipeError:
        # Output piped into a reader that stopped (e.g. `| head`): not an error.
        sys.stderr.close()
        return 0
    except OSError as exc:  # the machine's, not the input's: a full disk, a read-only folder
        print(f"rigkit {args.command}: error: {_shown(environment_message(exc))}",
              file=sys.stderr)
        return 2
    return code


def _check_outputs(parser: argparse.ArgumentParser, args: argparse.Namespace) -> None:
    """Every output the command line names (an argument whose type has an
    ``output_kind``: :class:`rigkit.commands.OutputPath`), in the subcommands chosen,
    checked by the one rule for outputs (:mod:`rigkit.core.outputs`) before the command
    starts; options not given (None) are left out."""
    from rigkit.core.outputs import CHECKS

    for action in _chosen_actions(parser, args):
        kind = getattr(action.type, "output_kind", None)
        value = getattr(args, action.dest, None)
        if kind is None or value is None:
            continue
        name = action.option_strings[-1] if action.option_strings else \
            (action.metavar if isinstance(action.metavar, str) else action.dest).upper()
        for path in value if isinstance(value, list) else [value]:
            CHECKS[kind](path, name)


def _chosen_actions(parser: argparse.ArgumentParser, args: argparse.Namespace
                    ) -> list[argparse.Action]:
    """The actions of ``parser`` and of each subparser ``args`` chose, top down."""
    actions: list[argparse.Action] = []
    current: argparse.ArgumentParser | None = parser
    while current is not None:
        actions += current._actions
        chosen = None
        for action in current._actions:
            if isinstance(action, argparse._SubParsersAction):
                chosen = action.choices.get(str(getattr(args, action.dest, "")))
        current = chosen
    return actions


def _shown(message: str) -> str:
    """An error message as one line that names, never obeys, what it quotes (a file
    name's escapes or newlines: :func:`rigkit.core.tables.visible`)."""
    from rigkit.core.tables import visible

    return visible(message, lines=False)


def _runner(path: str) -> Callable[[argparse.Namespace], int]:
    """The function a command's arguments name as ``module:function``
    (:mod:`rigkit.commands`), imported now that the command runs."""
    module, _, function = path.partition(":")
    return getattr(importlib.import_module(module), function)


def _printable_names() -> None:
    """A path whose bytes are not UTF-8 (a card's folder, an archive's) reaches Python as
    text with lone surrogates; printed, it shows as ``\udcff`` escapes instead of
    stopping the command."""
    for stream in (sys.stdout, sys.stderr):
        with contextlib.suppress(AttributeError, ValueError):
            stream.reconfigure(errors="backslashreplace")  # type: ignore[union-attr]


def _interrupted(who: str, exc: KeyboardInterrupt) -> int:
    """One line, and the shell's status for Ctrl-C (130) or SIGTERM (143)."""
    terminated = isinstance(exc, Terminated)
    print(f"{who}: {'terminated' if terminated else 'interrupted'}", file=sys.stderr)
    return 143 if terminated else 130


@contextlib.contextmanager
def _quiet_libraries() -> Iterator[None]:
    """What libraries print on their own is not for the command line's user: Python
    warnings (numpy's "Mean of empty slice", scipy's fit warnings) are dropped, and
    matplotlib logs only errors ("building the font cache" on a first run is not one).
    Decoders' output on descriptor 2 is captured where they run (rigkit.core.chatter)."""
    logging.getLogger("matplotlib").setLevel(logging.ERROR)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        yield


if __name__ == "__main__":
    sys.exit(main())
