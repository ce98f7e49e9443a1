"""CLI subcommands, each in two modules.

``NAME.py`` declares a command's arguments, help and examples: its
``register(subparsers)`` adds one subparser and sets ``runner`` to the dotted path,
``"rigkit.commands.NAME_run:function"``, of the function ``(argparse.Namespace) -> int``
that runs it and returns the exit code. ``rigkit --help``, ``rigkit COMMAND --help`` and
a mistyped command build the whole parser, so ``NAME.py`` imports nothing but the
standard library and this package's argument modules. ``NAME_run.py`` is the code, free
to import what it needs: ``rigkit.cli`` imports it only when its command runs. A value
the help shows that the library uses too (a default, a list of choices) lives once, in a
light module of its layer that both import (``rigkit.rig.defaults``,
``rigkit.rangefinder.defaults``, ``rigkit.experiments.defaults``,
``rigkit.export.defaults``); tests/commands/
test_loading.py holds help to importing nothing else.
"""

from __future__ import annotations

import argparse
import math
from collections.abc import Callable
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


def within(low: float, high: float, unit: str, *, low_open: bool = False
           ) -> Callable[[str], float]:
    """An argparse type: a finite number in [low, high] (``low_open``: above ``low``), in
    ``unit``; the limits named where it is not (a budget's 1e300 px overflowed the
    arithmetic behind it)."""

    def number(text: str) -> float:
        value = finite(text)
        if not (value > low if low_open else value >= low) or value > high:
            above = f"> {low:g}" if low_open else f">= {low:g}"
            raise argparse.ArgumentTypeError(f"must be {above} and <= {high:g} {unit}, "
                                             f"got {text}")
        return value

    return number


def count(text: str) -> int:
    """An argparse type: a whole number >= 1 (frames, readings, ...)."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a whole number: {text!r}") from None
    if value < 1:
        raise argparse.ArgumentTypeError(f"must be at least 1, got {text}")
    return value


class OutputPath:
    """An argparse type for a path the command writes: a file (``--out D.npy``), a
    folder it writes into or creates, or a log it appends to (``output_kind``).
    ``rigkit.cli`` checks every option of such a type by the one rule for outputs
    (:mod:`rigkit.core.outputs`) before the command runs."""

    def __init__(self, output_kind: str) -> None:
        self.output_kind = output_kind
        self.__name__ = f"output_{output_kind}"  # argparse names the type in errors

    def __call__(self, text: str) -> Path:
        return Path(text)


output_file = OutputPath("file")
output_folder = OutputPath("folder")
output_log = OutputPath("log")
