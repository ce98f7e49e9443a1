"""What every screen of the field TUI shares: the app's state as screens may read it,
the one rule by which workers' results reach screens, the step screens' navigation and
laser line, and how checks and errors are shown."""

from __future__ import annotations

import threading
from collections.abc import Callable
from typing import Any, Protocol, cast

from textual.binding import Binding
from textual.message import Message
from textual.screen import Screen
from textual.widgets import Static

from rigkit.capture import Session
from rigkit.capture.field import next_move
from rigkit.capture.model import FIELD_STEPS
from rigkit.core.tables import visible
from rigkit.rig.findings import Finding
from rigkit.tui.config import FieldConfig
from rigkit.tui.laser import LaserDesk
from rigkit.tui.messages import Done, FrameChecked, Goto, LaserChanged, Tidings

STEPS = FIELD_STEPS
"""The steps of a capture, in order; ``n`` and ``b`` move along them."""


class FieldHost(Protocol):
    """What screens read of the app (:class:`rigkit.tui.app.FieldApp`); they change it
    only through messages (:mod:`rigkit.tui.messages`)."""

    config: FieldConfig
    session: Session | None
    stop: threading.Event
    laser: LaserDesk
    processing: threading.Lock

    def outcome(self, session: Session, position: str) -> FrameChecked | None:
        """The checks last shown for ``position``, while its frames are as they were."""


def host(screen: Screen[Any]) -> FieldHost:
    """The running app, as screens may see it."""
    return cast(FieldHost, screen.app)


def session_of(screen: Screen[Any]) -> Session:
    session = host(screen).session
    assert session is not None, "a step screen needs an open session"
    return session


def step_after(step: str, offset: int) -> str | None:
    """The step ``offset`` places after (before, when negative) ``step``, or None."""
    index = STEPS.index(step) + offset
    return STEPS[index] if 0 <= index < len(STEPS) else None


def escape(text: str) -> str:
    """``text`` safe to put in markup: shown as it is, never obeyed as markup or by the
    terminal (:func:`rigkit.core.tables.visible`)."""
    return visible(text, markup=True)


def check_lines(checks: list[Finding]) -> str:
    """Checks as Rich markup, what to do next first: the one redo of
    :func:`rigkit.capture.field.next_move`, then the failed checks, then those that
    passed, each with a tick or a cross."""
    first = next_move(checks)
    lines = [f"[b $warning]redo:[/] {escape(first)}"] if first else []
    for check in sorted(checks, key=lambda c: c.ok):  # stable: failures first, in order
        mark = "[b $success]✔[/]" if check.ok else "[b $error]✘[/]"
        lines.append(f"{mark} {escape(check.message)}")
    return "\n".join(lines)


class LaserLine(Static):
    """One line on every step screen: the laser's link, its newest shot, and the shots
    held until a target takes them (:meth:`rigkit.tui.laser.LaserDesk.line`)."""

    DEFAULT_CSS = "LaserLine { height: auto; max-height: 2; padding: 0 1; }"

    def __init__(self, always: bool = False) -> None:
        """``always``: shown even with no rangefinder and no shot (the targets step,
        where ranges are typed in)."""
        super().__init__()
        self.always = always

    def on_mount(self) -> None:
        self.show_desk()

    def show_desk(self) -> None:
        desk = cast(FieldHost, self.app).laser
        self.display = self.always or desk.worth_saying()
        held = bool(desk.held()) and desk.selected is None
        self.update(f"[b $warning]{escape(desk.line())}[/]" if held else escape(desk.line()))


class FieldScreen(Screen[None]):
    """A screen of the field TUI, and the one rule by which work done in the background
    reaches it (docs/architecture.md, "The field TUI's workers and screens"): what a
    worker finished arrives as a :class:`Tidings` message, which the screen handles only
    while it is the screen on show. A screen's own workers are Textual workers of the
    screen (``@work`` on its methods: cancelled when it is removed) and hand their result
    over with :meth:`deliver`; the app's workers (frames, the laser) post theirs to the
    screen on show. A screen replaced meanwhile drops them unread, so nothing updates a
    screen whose widgets are gone."""

    def deliver(self, call: Callable[..., Any], *args: Any) -> None:
        """From a worker thread: ``call(*args)`` on this screen's thread, if it is still
        on show then."""
        self.post_message(Done(call, args))

    async def _on_message(self, message: Message) -> None:
        if isinstance(message, Tidings) and not self.showing():
            return  # a result for a screen no longer on show: dropped, never a crash
        await super()._on_message(message)

    def showing(self) -> bool:
        """Mounted and on show (not replaced, not being removed)."""
        return self.is_mounted and self.is_active and self.is_attached

    def on_done(self, message: Done) -> None:
        message.call(*message.args)

    def on_laser_changed(self, message: LaserChanged) -> None:
        for line in self.query(LaserLine):
            line.show_desk()

    def check_action(self, action: str, parameters: tuple[object, ...]) -> bool | None:
        """Keys act on a screen on show only (a key read while the next screen mounts
        waits for it)."""
        return True if self.showing() else None


class StepScreen(FieldScreen):
    """A step of the flow: header, footer with key hints, ``n``/``b`` to move on/back."""

    step = ""
    BINDINGS = [
        Binding("n", "next", "next"),
        Binding("b", "back", "back"),
    ]

    def action_next(self) -> None:
        self._move(+1)

    def action_back(self) -> None:
        self._move(-1)

    def _move(self, offset: int) -> None:
        step = step_after(self.step, offset)
        if step is not None:
            self.post_message(Goto(step))
