"""The messages the field TUI's screens and its app send each other.

Screens never call the app: they post what the user asked for (go to a step, open a
session, add a file) and the app, which owns the session and the background workers,
handles it. The app tells the screen on show what became of a frame or a laser shot
the same way. Textual calls ``on_<message name>`` on whoever the message reaches (a
screen's messages bubble up to the app).

What a worker finished is a :class:`Tidings`: a screen handles one only while it is the
screen on show (:class:`rigkit.tui.screens.common.FieldScreen`), so a result never
reaches a screen that was replaced meanwhile (docs/architecture.md, "The field TUI's
workers and screens").
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
from textual.message import Message

from rigkit.capture import Session
from rigkit.rig.findings import Finding

# -- from a screen to the app ----------------------------------------------------------------


class Goto(Message):
    """Show ``step`` (``rig``, ``left``, ``right``, ``back``, ``targets``, ``process``);
    ``resume``: opening a session, so the process step shows its latest run."""

    def __init__(self, step: str, resume: bool = False) -> None:
        super().__init__()
        self.step, self.resume = step, resume


class OpenSession(Message):
    """Work on ``session`` from where it stopped."""

    def __init__(self, session: Session) -> None:
        super().__init__()
        self.session = session


class SessionChanged(Message):
    """A screen or a worker changed the session (through :mod:`rigkit.capture`); the app
    reads it again from its folder."""

    def __init__(self, session: Session) -> None:
        super().__init__()
        self.session = session


class IngestFile(Message):
    """Add the file at ``path`` to ``position``, as if it had arrived in the card folder;
    ``retake``: in place of the position's frames, and without asking whether it fits
    them."""

    def __init__(self, path: Path, position: str, retake: bool = False) -> None:
        super().__init__()
        self.path, self.position, self.retake = path, position, retake


class CheckPosition(Message):
    """Show the on-site checks of ``position``'s newest frame (run them where the app
    has none for it)."""

    def __init__(self, position: str) -> None:
        super().__init__()
        self.position = position


class TypedReading(Message):
    """A range typed in (m), for the selected target."""

    def __init__(self, range_m: float) -> None:
        super().__init__()
        self.range_m = range_m


class TargetSelected(Message):
    """The selected target changed (:attr:`rigkit.tui.laser.LaserDesk.selected`): the
    shots held go to it now."""


class AimDemo(Message):
    """The demo's simulated laser, aimed at ``pixel`` of the full-resolution left frame:
    it fires a few shots there."""

    def __init__(self, pixel: tuple[float, float]) -> None:
        super().__init__()
        self.pixel = pixel


# -- from a worker to the screen on show -----------------------------------------------------


class Tidings(Message):
    """What a worker finished, for the screen on show; a screen no longer on show
    ignores it."""


class Done(Tidings):
    """A screen's own worker finished: ``call(*args)`` shows its result on that screen
    (:meth:`rigkit.tui.screens.common.FieldScreen.deliver`)."""

    def __init__(self, call: Callable[..., Any], args: tuple[Any, ...]) -> None:
        super().__init__()
        self.call, self.args = call, args


class FrameArrived(Tidings):
    """The file ``name`` arrived for ``position``; ``ahead``: frames before it in the
    queue (the checks run in arrival order)."""

    def __init__(self, position: str, name: str, ahead: int) -> None:
        super().__init__()
        self.position, self.name, self.ahead = position, name, ahead


class FrameAdded(Tidings):
    """The file ``name`` was added to ``position`` as its frame ``number`` (1: the
    first or a retake); its checks are running."""

    def __init__(self, position: str, name: str, number: int = 1) -> None:
        super().__init__()
        self.position, self.name, self.number = position, name, number


class FrameHeld(Tidings):
    """The file at ``path`` arrived for ``position`` but does not match its burst
    (``reason``): it is held back, not added, until the operator says where it goes.
    ``elsewhere``: it looks taken from another position (else it matches nothing: another
    scene, a blank frame)."""

    def __init__(self, position: str, path: Path, reason: str, elsewhere: bool) -> None:
        super().__init__()
        self.position, self.path, self.reason = position, path, reason
        self.elsewhere = elsewhere


class FrameRefused(Tidings):
    """A file for ``position`` could not be added or checked: ``reason``, one line."""

    def __init__(self, position: str, reason: str) -> None:
        super().__init__()
        self.position, self.reason = position, reason


class FrameChecked(Tidings):
    """``position``'s newest frame (``name``, the burst's frame ``number``) was checked:
    ``checks``, and ``image`` to preview ((h, w) float32 grey)."""

    def __init__(self, position: str, name: str, number: int, checks: list[Finding],
                 image: np.ndarray) -> None:
        super().__init__()
        self.position, self.name, self.number = position, name, number
        self.checks, self.image = checks, image


class CardFrames(Tidings):
    """Frames on the card that the session does not hold (:func:`rigkit.tui.watch.unfiled`),
    oldest first."""

    def __init__(self, paths: list[Path]) -> None:
        super().__init__()
        self.paths = paths


class LaserChanged(Tidings):
    """The laser's state changed (a shot, the link, a reading filed or held): the screen
    on show says it again (:class:`rigkit.tui.laser.LaserDesk`)."""
