"""A camera position's step: its checklist, the frames as they arrive, their checks."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from textual import work
from textual.app import ComposeResult
from textual.binding import Binding
from textual.containers import Horizontal, Vertical
from textual.widgets import Footer, Header, Input, Static

from rigkit.capture import Session
from rigkit.capture.field import frames_at
from rigkit.rig.findings import Finding
from rigkit.tui.messages import CheckPosition, FrameAdded, FrameChecked, FrameRefused, IngestFile
from rigkit.tui.previews import preview_widget
from rigkit.tui.screens.common import StepScreen, check_lines, escape, host, session_of

CHECKLISTS = {
    "left": (
        "camera in manual mode (M), fixed ISO, fixed white balance",
        "zoom set and noted; focus locked (MF)",
        "vibration reduction off (on a tripod)",
        "RAW (NRW) on; self-timer or remote release",
        "burst of several frames: shimmer averages out",
    ),
    "right": (
        "tripod moved C_lr to the right, same height",
        "same zoom, focus, ISO and exposure as the left frame",
        "aim at the same scene; keep the camera level",
    ),
    "back": (
        "tripod moved C_lb straight back from the LEFT position",
        "C_lb measured with the tape: {c_lb}",
        "same zoom, focus, ISO and exposure as before",
    ),
}


class PositionScreen(StepScreen):
    """One camera position: its checklist, the frames as they arrive, their checks."""

    BINDINGS = [Binding("o", "open_file", "add file")]

    def __init__(self, position: str) -> None:
        super().__init__()
        self.position = position
        self.step = position
        self._shown = ""  # the newest frame's checks, as markup

    def compose(self) -> ComposeResult:
        yield Header()
        with Horizontal():
            with Vertical(id="side"):
                yield Static(self._checklist(), id="checklist")
                yield Static(self._waiting(), id="checks")
            yield Vertical(id="preview")
        yield Input(placeholder="path of a frame file, then Enter (Esc: cancel)", id="path")
        yield Footer()

    def _checklist(self) -> str:
        c_lb = f"{session_of(self).rig().baseline_lb.value_m:g} m in the profile"
        items = [item.format(c_lb=c_lb) for item in CHECKLISTS[self.position]]
        return f"[b]{self.position.upper()} position[/]\n" + "\n".join(f"• {i}" for i in items)

    def _waiting(self) -> str:
        app = host(self)
        folder = app.config.demo.card if app.config.demo else app.config.watch
        source = f"watching {folder}" if folder else "no folder watched"
        return f"{source}\nwaiting for the {self.position} frame (o: add a file)"

    def on_mount(self) -> None:
        self.query_one("#path", Input).display = False
        session = session_of(self)
        app = host(self)
        if frames_at(session, self.position):
            self.show_added(Path(frames_at(session, self.position)[-1].file).name)
            self._recheck(session)
        elif app.config.demo is not None:
            self._demo_shoot()

    def _recheck(self, session: Session) -> None:
        self.post_message(CheckPosition(self.position))

    @work(thread=True, group="demo")
    def _demo_shoot(self) -> None:
        demo = host(self).config.demo
        assert demo is not None
        number = 100 + ("left", "right", "back").index(self.position)
        demo.shoot(self.position, number)

    def on_frame_added(self, message: FrameAdded) -> None:
        if message.position == self.position:
            self.show_added(message.name)

    def on_frame_refused(self, message: FrameRefused) -> None:
        """A file that could not be added or checked; the position keeps what it had."""
        if message.position == self.position:
            self.query_one("#checks", Static).update(
                f"[b $error]✘ {escape(message.reason)}[/]\n{self._shown}")

    def on_frame_checked(self, message: FrameChecked) -> None:
        if message.position == self.position:
            self.show_checks(message.checks, message.image)

    def show_added(self, name: str) -> None:
        self.query_one("#checks", Static).update(f"frame {name}: checking ...")

    def show_checks(self, checks: list[Finding], image: np.ndarray) -> None:
        """The newest frame's checks, and its preview."""
        frames = frames_at(session_of(self), self.position)
        burst = f" ({len(frames)} frames)" if len(frames) > 1 else ""
        hint = "\n[b]n[/]: next step" if all(c.ok for c in checks) else ""
        self._shown = f"frame {Path(frames[-1].file).name}{burst}\n{check_lines(checks)}{hint}"
        self.query_one("#checks", Static).update(self._shown)
        preview = self.query_one("#preview", Vertical)
        preview.remove_children()
        preview.mount(preview_widget(image, host(self).config.graphics))

    def action_open_file(self) -> None:
        entry = self.query_one("#path", Input)
        entry.display = True
        entry.focus()

    def on_input_submitted(self, event: Input.Submitted) -> None:
        self.keyescape()
        if event.value.strip():
            self.post_message(IngestFile(Path(event.value.strip()).expanduser(), self.position))
        event.input.value = ""

    def keyescape(self) -> None:
        """Close the entry box; keys go to the screen again."""
        self.query_one("#path", Input).display = False
        self.set_focus(None)
