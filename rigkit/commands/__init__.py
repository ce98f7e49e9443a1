"""CLI subcommands, each in two modules.

``NAME.py`` declares a command's arguments, help and examples: its
``register(subparsers)`` adds one subparser and sets ``runner`` to the dotted path,
``"rigkit.commands.NAME_run:function"``, of the function ``(argparse.Namespace) -> int``
that runs it and returns the exit code. ``rigkit --help``, ``rigkit COMMAND --help`` and
a mistyped command build the whole parser, so ``NAME.py`` imports nothing but the
standard library and this package's argument modules. ``NAME_run.py`` is the code, free
to import what it needs: ``rigkit.cli`` imports it only when its command runs. A value
the help shows that lives in a heavy module (a default, a list of choices) is repeated
in ``NAME.py``, and tests/commands/test_loading.py holds each copy to its original.
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from rigkit.geometry import Distortion


def parse_distortion(text: str) -> Distortion:
    """``--distortion K1[,K2[,P1,P2[,K3]]]`` as OpenCV's five coefficients; InputError
    naming the flag and value otherwise."""
    from rigkit.errors import InputError
    from rigkit.geometry import distortion_coefficients

    try:
        return distortion_coefficients([float(x) for x in text.split(",")])
    except ValueError as exc:
        raise InputError(f"--distortion {text!r}: {exc}") from None


def finite(text: str) -> float:
    """An argparse type: a finite number (``nan`` and ``inf``, which ``float`` takes, are
    refused with the flag named)."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a number: {text!r}") from None
    if not math.isfinite(value):
        raise argparse.ArgumentTypeError(f"must be a finite number, got {text}")
    return value


def count(text: str) -> int:
    """An argparse type: a whole number >= 1 (frames, readings, ...)."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a whole number: {text!r}") from None
    if value < 1:
        raise argparse.ArgumentTypeError(f"must be at least 1, got {text}")
    return value


def output_file(text: str) -> Path:
    """An argparse type: a file the command writes (``--out D.npy``). ``rigkit.cli``
    checks every option of this type before the command runs, by the one rule for
    outputs (:mod:`rigkit.core.outputs`)."""
    return Path(text)


def output_folder(text: str) -> Path:
    """An argparse type: a folder the command writes into or creates (as
    :func:`output_file`)."""
    return Path(text)


def output_log(text: str) -> Path:
    """An argparse type: a log the command appends to (as :func:`output_file`)."""
    return Path(text)


OUTPUT_KINDS = {output_file: "file", output_folder: "folder", output_log: "log"}
"""Each output type and the kind of output it declares (:data:`rigkit.core.outputs.CHECKS`)."""


def output_values(parser: argparse.ArgumentParser, args: argparse.Namespace
                  ) -> list[tuple[str, str, Path]]:
    """The outputs the parsed ``args`` name: (option as the user wrote it, kind, path)
    for every argument of an output type in the subcommands chosen, in ``parser``'s
    order; options not given (None) are left out."""
    found = []
    for action in _chosen_actions(parser, args):
        kind = OUTPUT_KINDS.get(action.type)  # type: ignore[arg-type]
        value = getattr(args, action.dest, None)
        if kind is None or value is None:
            continue
        name = action.option_strings[-1] if action.option_strings else \
            (action.metavar if isinstance(action.metavar, str) else action.dest).upper()
        for path in value if isinstance(value, list) else [value]:
            found.append((name, kind, path))
    return found


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
