"""The messages the field TUI's screens and its app send each other.

Screens never call the app: they post what the user asked for (go to a step, open a
session, add a file) and the app, which owns the session and the background workers,
handles it. The app tells a position's screen what became of a frame the same way.
Textual calls ``on_<message name>`` on whoever the message reaches (a screen's
messages bubble up to the app).
"""

from __future__ import annotations

from pathlib import Path

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
    """A screen changed the session (through :mod:`rigkit.capture`); this is it now."""

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
    """Run the on-site checks of ``position``'s newest frame again."""

    def __init__(self, position: str) -> None:
        super().__init__()
        self.position = position


# -- from the app to a position's screen -----------------------------------------------------


class FrameAdded(Message):
    """The file ``name`` was added to ``position``; its checks are running."""

    def __init__(self, position: str, name: str) -> None:
        super().__init__()
        self.position, self.name = position, name


class FrameHeld(Message):
    """The file at ``path`` arrived for ``position`` but does not match its burst
    (``reason``): it is held back, not added, until the operator says where it goes."""

    def __init__(self, position: str, path: Path, reason: str) -> None:
        super().__init__()
        self.position, self.path, self.reason = position, path, reason


class FrameRefused(Message):
    """A file for ``position`` could not be added or checked: ``reason``, one line."""

    def __init__(self, position: str, reason: str) -> None:
        super().__init__()
        self.position, self.reason = position, reason


class FrameChecked(Message):
    """``position``'s newest frame was checked: ``checks``, and ``image`` to preview
    ((h, w) float32 grey)."""

    def __init__(self, position: str, checks: list[Finding], image: np.ndarray) -> None:
        super().__init__()
        self.position, self.checks, self.image = position, checks, image


class CardFrames(Message):
    """Frames on the card that the session does not hold (:func:`rigkit.tui.watch.unfiled`),
    oldest first."""

    def __init__(self, paths: list[Path]) -> None:
        super().__init__()
        self.paths = paths
