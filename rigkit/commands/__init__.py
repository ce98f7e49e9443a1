"""CLI subcommands: each module exposes ``register(subparsers)``.

A module's ``register`` adds one subparser and sets ``func`` to a callable
``(argparse.Namespace) -> int`` that returns the exit code.
"""

from __future__ import annotations

import argparse
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


def count(text: str) -> int:
    """An argparse type: a whole number >= 1 (frames, readings, ...)."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a whole number: {text!r}") from None
    if value < 1:
        raise argparse.ArgumentTypeError(f"must be at least 1, got {text}")
    return value
