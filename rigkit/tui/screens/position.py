"""A camera position's step: its checklist, the frames as they arrive, their checks."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from textual import work
from textual.app import ComposeResult
from textual.binding import Binding
from textual.containers import Horizontal, Vertical, VerticalScroll
from textual.widgets import Footer, Input, Static
from textual.worker import get_current_worker

from rigkit.capture import Session
from rigkit.capture.actions import remove_frame
from rigkit.capture.field import frames_at, metres, next_move
from rigkit.tui.header import FieldHeader
from rigkit.tui.messages import (
    CardFrames,
    CheckPosition,
    FrameAdded,
    FrameArrived,
    FrameChecked,
    FrameHeld,
    FrameRefused,
    Goto,
    IngestFile,
    SessionChanged,
)
from rigkit.tui.previews import central, preview_widget
from rigkit.tui.screens.common import (
    LaserLine,
    StepScreen,
    check_lines,
    escape,
    host,
    session_of,
    step_after,
)
from rigkit.tui.watch import unfiled

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

    BINDINGS = [
        Binding("a", "place_here", "again with it"),  # these three only while a frame
        Binding("f", "place_next", "to next"),  # is held with a question
        Binding("escape", "leave_on_card", "leave on card"),
        Binding("o", "open_file", "file"),
        Binding("c", "from_card", "card"),
        Binding("x", "drop_frame", "drop"),
        Binding("down", "scroll(1)", "scroll", key_display="↑↓"),
        Binding("up", "scroll(-1)", show=False),
        Binding("pagedown", "scroll(8)", show=False),
        Binding("pageup", "scroll(-8)", show=False),
    ]
    QUESTION_ACTIONS = frozenset({"place_here", "place_next", "leave_on_card"})

    def __init__(self, position: str) -> None:
        super().__init__()
        self.position = position
        self.step = position
        self.failed = ""  # what to redo after the newest frame's checks, if one failed
        self.held: FrameHeld | None = None  # a frame that arrived but does not fit the burst
        self.confirm = False  # n pressed once after a failed check
        self.dropping = ""  # the frame x was pressed once for
        self.card: list[Path] = []  # frames on the card the session does not hold

    def compose(self) -> ComposeResult:
        yield FieldHeader()
        with Horizontal():
            with VerticalScroll(id="side"):  # what does not fit scrolls (↑↓), never cut off
                yield Static("", id="title")
                yield Static(self._checklist(), id="checklist")
                yield Static("", id="question")
                yield Static("", id="status")
                yield Static("", id="checks")
                yield Static("", id="card")
            yield Vertical(id="preview")
        yield Input(placeholder="path of a frame file, then Enter (Esc: cancel)", id="path")
        yield LaserLine()
        yield Footer(compact=True)

    def _checklist(self) -> str:
        rig = session_of(self).rig()
        c_lb = f"{metres(rig.baseline_lb.value_m)} in the profile" + (
            " (laser-calibrated: the same set-up)" if rig.calibration else "")
        items = [item.format(c_lb=c_lb) for item in CHECKLISTS[self.position]]
        return "\n".join(f"• {i}" for i in items)

    def _folder(self) -> Path | None:
        app = host(self)
        return app.config.demo.card if app.config.demo else app.config.watch

    def _waiting(self) -> str:
        folder = self._folder()
        source = f"watching {escape(str(folder))}" if folder else "no folder watched"
        return f"{source}\nwaiting for the {self.position} frame (o: add a file)"

    def check_action(self, action: str, parameters: tuple[object, ...]) -> bool | None:
        """The question's keys only while a frame is held (``f`` where a position
        follows); the card's ``c`` while the card has frames for it."""
        if action in self.QUESTION_ACTIONS and self.held is None:
            return False
        if action == "place_next" and step_after(self.position, +1) not in CHECKLISTS:
            return False
        return super().check_action(action, parameters)

    def on_mount(self) -> None:
        self.query_one("#path", Input).display = False
        self.query_one("#card", Static).display = False
        self.query_one("#question", Static).display = False
        self._show_title()
        self._look_at_card()
        session = session_of(self)
        frames = frames_at(session, self.position)
        known = host(self).outcome(session, self.position)
        if known is not None:
            self.on_frame_checked(known)
        elif frames:
            self._status(f"frame {escape(Path(frames[-1].file).name)}: checking ...")
            self.post_message(CheckPosition(self.position))
        else:
            self._status(self._waiting())
            if host(self).config.demo is not None:
                self._demo_shoot()

    def _show_title(self, session: Session | None = None) -> None:
        count = len(frames_at(session or session_of(self), self.position))
        burst = "" if count == 0 else " · 1 frame" if count == 1 else f" · {count} frames"
        self.query_one("#title", Static).update(f"[b]{self.position.upper()} position[/]{burst}")
        self.query_one("#checklist", Static).display = count == 0  # before the first frame

    def _status(self, markup: str) -> None:
        self.query_one("#status", Static).update(markup)

    @work(thread=True, exclusive=True, group="card")
    def _look_at_card(self) -> None:
        """List the card's frames the session does not hold (card I/O: a worker)."""
        folder = self._folder()
        if folder is not None and folder.is_dir():
            self.post_message(CardFrames(unfiled(folder, session_of(self))))

    def on_card_frames(self, message: CardFrames) -> None:
        self.card = message.paths
        card = self.query_one("#card", Static)
        card.display = bool(self.card)
        if self.card:
            more = f" (+{len(self.card) - 1} more)" if len(self.card) > 1 else ""
            card.update(f"[b $warning]on the card, not in the session:[/] "
                        f"{escape(self.card[0].name)}{more} · [b]c[/]: add it here")

    def action_from_card(self) -> None:
        """Add the oldest frame the card holds and the session does not, to this
        position, as if it had just arrived."""
        if self.card:
            self.post_message(IngestFile(self.card.pop(0), self.position))
        else:
            self.notify("no frame on the card that the session does not hold")

    @work(thread=True, exclusive=True, group="demo")
    def _demo_shoot(self) -> None:
        """The demo's camera: a burst for this position, one frame at a time, until the
        screen is left."""
        demo = host(self).config.demo
        assert demo is not None
        worker = get_current_worker()
        for number in range(demo.burst):
            if worker.is_cancelled or host(self).stop.is_set():
                return
            demo.shoot(self.position, number)

    def on_frame_arrived(self, message: FrameArrived) -> None:
        if message.position == self.position:
            ahead = f" (after {message.ahead} more)" if message.ahead else ""
            self._status(f"{escape(message.name)} arrived: adding{ahead} ...")

    def on_frame_added(self, message: FrameAdded) -> None:
        if message.position == self.position:
            self._show_title()
            self._status(f"{escape(message.name)}: {self.position} frame {message.number}; "
                         "checking ...")

    def on_frame_refused(self, message: FrameRefused) -> None:
        """A file that could not be added or checked; the position keeps what it had."""
        if message.position == self.position:
            self._status(f"[b $error]✘ {escape(message.reason)}[/]")
            self._look_at_card()

    def on_frame_checked(self, message: FrameChecked) -> None:
        if message.position == self.position:
            self._show_title()
            self.show_checks(message)
            self._look_at_card()

    def on_frame_held(self, message: FrameHeld) -> None:
        """A frame that does not fit this position's burst: ask where it goes. One of
        another scene is never offered to a position first."""
        if message.position != self.position:
            return
        self.held = message
        after = step_after(self.position, +1)
        keys = []
        if after in CHECKLISTS:
            keys.append(f"[b]f[/]: add it to the {after.upper()} position")
        keys.append(f"[b]a[/]: start the {self.position.upper()} position again with it")
        keys.append("[b]Esc[/]: leave it on the card")
        if not message.elsewhere:  # another scene: leaving it is the first choice
            keys.insert(0, keys.pop())
        question = self.query_one("#question", Static)
        question.display = True
        question.update(f"[b $warning]? {escape(message.reason)}[/]\n" + " · ".join(keys))
        self._status("")
        self.refresh_bindings()

    def _answered(self) -> None:
        self.held = None
        self.query_one("#question", Static).display = False
        self.refresh_bindings()
        self._look_at_card()

    def show_checks(self, checked: FrameChecked) -> None:
        """The newest frame's checks, what to redo first, and its preview."""
        frames = frames_at(session_of(self), self.position)
        self.failed = next_move(checked.checks) or ""
        self.confirm = False
        of = f" of {len(frames)}" if len(frames) > 1 else ""
        hint = "" if self.failed else "\n[b]n[/]: next step"
        self._status(f"frame {escape(checked.name)} ({self.position} frame "
                     f"{checked.number}{of})")
        self.query_one("#checks", Static).update(check_lines(checked.checks) + hint)
        self._show_preview(checked.image)

    def _show_preview(self, image: np.ndarray) -> None:
        preview = self.query_one("#preview", Vertical)
        preview.remove_children()
        preview.border_title = "the frame's centre"
        preview.mount(preview_widget(central(image), host(self).config.graphics))

    def action_scroll(self, lines: int) -> None:
        side = self.query_one("#side", VerticalScroll)
        side.scroll_relative(y=lines, animate=False)

    def action_open_file(self) -> None:
        entry = self.query_one("#path", Input)
        entry.display = True
        entry.focus()

    def on_input_submitted(self, event: Input.Submitted) -> None:
        self._close_entry()
        if event.value.strip():
            path = Path(event.value.strip()).expanduser()
            self.post_message(IngestFile(path, self.position))
        event.input.value = ""

    def key_escape(self) -> None:
        """Close the entry box (keys go to the screen again)."""
        self._close_entry()

    def _close_entry(self) -> None:
        self.query_one("#path", Input).display = False
        self.set_focus(None)

    def action_leave_on_card(self) -> None:
        """Leave the held frame on the card (``c`` adds it later)."""
        if self.held is not None:
            self.notify(f"{escape(self.held.path.name)} left on the card")
            self._answered()

    def action_place_here(self) -> None:
        """Start this position again with the held frame (the earlier ones stay in raw/)."""
        if self.held is not None:
            self.post_message(IngestFile(self.held.path, self.position, retake=True))
            self._answered()

    def action_place_next(self) -> None:
        """Add the held frame to the next position, and go there."""
        after = step_after(self.position, +1)
        if self.held is not None and after in CHECKLISTS:
            self.post_message(IngestFile(self.held.path, after))
            self._answered()
            self.post_message(Goto(after))

    def action_drop_frame(self) -> None:
        """Take the newest frame out of the position (its file stays in raw/), once
        ``x`` is pressed a second time for the same frame, as targets are dropped."""
        frames = frames_at(session_of(self), self.position)
        if not frames:
            return
        name = Path(frames[-1].file).name
        if self.dropping != frames[-1].file:
            self.dropping = frames[-1].file
            self.notify(f"press x again to take {escape(name)} out of the {self.position} "
                        "position (its file stays in raw/)", severity="warning", timeout=8)
            return
        self.dropping = ""
        session = remove_frame(session_of(self), self.position)
        self.post_message(SessionChanged(session))
        self.notify(f"{escape(name)} taken out of the {self.position} position (the file "
                    "stays in raw/)")
        self._show_title(session)
        if frames_at(session, self.position):
            self._status("checking the frame before it ...")
            self.post_message(CheckPosition(self.position))
        else:
            self.query_one("#checks", Static).update("")
            self._status(self._waiting())

    def action_next(self) -> None:
        """Next step. After a failed check only on a second ``n``: moving on keeps a
        frame that will fail processing. A held frame stays on the card."""
        if self.failed and not self.confirm:
            self.confirm = True
            self.notify(f"the {self.position} frame failed a check; redo: "
                        f"{escape(self.failed)}. Press n again to go on anyway",
                        severity="warning", timeout=8)
            return
        self._leave_held()
        super().action_next()

    def action_back(self) -> None:
        self._leave_held()
        super().action_back()

    def _leave_held(self) -> None:
        if self.held is not None:
            self.notify(f"{escape(self.held.path.name)} stays on the card (c adds it)")
            self.held = None
