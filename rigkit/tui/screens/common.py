"""What every screen of the field TUI shares: the app's state as screens may read it,
the step screens' navigation, and how checks and errors are shown."""

from __future__ import annotations

import threading
from typing import Any, Protocol, cast

from textual.binding import Binding
from textual.screen import Screen

from rigkit.capture import Session
from rigkit.capture.model import FIELD_STEPS
from rigkit.core.tables import visible
from rigkit.rig.findings import Finding
from rigkit.tui.config import FieldConfig
from rigkit.tui.messages import Goto

STEPS = FIELD_STEPS
"""The steps of a capture, in order; ``n`` and ``b`` move along them."""


class FieldHost(Protocol):
    """What screens read of the app (:class:`rigkit.tui.app.FieldApp`); they change it
    only through messages (:mod:`rigkit.tui.messages`)."""

    config: FieldConfig
    session: Session | None
    stop: threading.Event


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
    """Checks as Rich markup: a tick or a cross, the message, and what to redo."""
    lines = []
    for check in checks:
        mark = "[b $success]✔[/]" if check.ok else "[b $error]✘[/]"
        lines.append(f"{mark} {escape(check.message)}")
        if check.redo:
            lines.append(f"  [b $warning]redo:[/] {escape(check.redo)}")
    return "\n".join(lines)


class StepScreen(Screen[None]):
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
