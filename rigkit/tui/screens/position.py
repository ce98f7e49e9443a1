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
from rigkit.capture.actions import remove_frame
from rigkit.capture.field import frames_at
from rigkit.rig.findings import Finding
from rigkit.tui.messages import (
    CardFrames,
    CheckPosition,
    FrameAdded,
    FrameChecked,
    FrameHeld,
    FrameRefused,
    IngestFile,
    SessionChanged,
)
from rigkit.tui.previews import central, preview_widget
from rigkit.tui.screens.common import (
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
        Binding("o", "open_file", "add file"),
        Binding("x", "drop_frame", "drop frame"),
        Binding("a", "place_here", "retake with it", show=False),
        Binding("c", "from_card", "add from the card", show=False),
    ]

    def __init__(self, position: str) -> None:
        super().__init__()
        self.position = position
        self.step = position
        self._shown = ""  # the newest frame's checks, as markup
        self.failed = ""  # the first failed check of the newest frame, if any
        self.held: Path | None = None  # a frame that arrived but does not fit the burst
        self.confirm = False  # n pressed once after a failed check
        self.dropping = ""  # the frame x was pressed once for
        self.card: list[Path] = []  # frames on the card the session does not hold

    def compose(self) -> ComposeResult:
        yield Header()
        with Horizontal():
            with Vertical(id="side"):
                yield Static(self._checklist(), id="checklist")
                yield Static("", id="card")
                yield Static(self._waiting(), id="checks")
            yield Vertical(id="preview")
        yield Input(placeholder="path of a frame file, then Enter (Esc: cancel)", id="path")
        yield Footer(compact=True)

    def _checklist(self) -> str:
        rig = session_of(self).rig()
        c_lb = f"{rig.baseline_lb.value_m:g} m in the profile" + (
            " (laser-calibrated: the same set-up)" if rig.calibration else "")
        items = [item.format(c_lb=c_lb) for item in CHECKLISTS[self.position]]
        return f"[b]{self.position.upper()} position[/]\n" + "\n".join(f"• {i}" for i in items)

    def _folder(self) -> Path | None:
        app = host(self)
        return app.config.demo.card if app.config.demo else app.config.watch

    def _waiting(self) -> str:
        folder = self._folder()
        source = f"watching {escape(str(folder))}" if folder else "no folder watched"
        return f"{source}\nwaiting for the {self.position} frame (o: add a file)"

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
            names = [p.name for p in self.card]
            shown = ", ".join(names[:3]) + (f" and {len(names) - 3} more" if len(names) > 3
                                            else "")
            card.update(f"[b $warning]{len(names)} on the card, not in the session:[/] "
                        f"{escape(shown)} · [b]c[/]: add {escape(names[0])} here")

    def action_from_card(self) -> None:
        """Add the oldest frame the card holds and the session does not, to this
        position, as if it had just arrived."""
        if self.card:
            self.post_message(IngestFile(self.card.pop(0), self.position))

    def on_mount(self) -> None:
        self.query_one("#path", Input).display = False
        self.query_one("#card", Static).display = False
        self._look_at_card()
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
            self._look_at_card()

    def on_frame_checked(self, message: FrameChecked) -> None:
        if message.position == self.position:
            self.show_checks(message.checks, message.image)
            self._look_at_card()

    def on_frame_held(self, message: FrameHeld) -> None:
        """A frame that does not fit this position's burst: ask where it goes."""
        if message.position != self.position:
            return
        self.held = message.path
        after = step_after(self.position, +1)
        where = f"n: add it to the {after} position" if after in CHECKLISTS else \
            "n: go on without it"
        self.query_one("#checks", Static).update(
            f"[b $warning]? {escape(message.reason)}[/]\n"
            f"{where} · a: start the {self.position} position again with it · Esc: leave "
            f"it on the card\n{self._shown}")

    def show_added(self, name: str) -> None:
        self.query_one("#checks", Static).update(f"frame {escape(name)}: checking ...")

    def show_checks(self, checks: list[Finding], image: np.ndarray) -> None:
        """The newest frame's checks, and its preview."""
        frames = frames_at(session_of(self), self.position)
        burst = f" ({len(frames)} frames)" if len(frames) > 1 else ""
        self.failed = next((c.message for c in checks if not c.ok), "")
        self.confirm = False
        hint = "" if self.failed else "\n[b]n[/]: next step"
        self._shown = (f"frame {escape(Path(frames[-1].file).name)}{burst}\n"
                       f"{check_lines(checks)}{hint}")
        self.query_one("#checks", Static).update(self._shown)
        preview = self.query_one("#preview", Vertical)
        if not preview.is_attached:  # the step was left while its check ran
            return
        preview.remove_children()
        preview.border_title = "the frame's centre"
        preview.mount(preview_widget(central(image), host(self).config.graphics))

    def action_open_file(self) -> None:
        entry = self.query_one("#path", Input)
        entry.display = True
        entry.focus()

    def on_input_submitted(self, event: Input.Submitted) -> None:
        self.key_escape()
        if event.value.strip():
            path = Path(event.value.strip()).expanduser()
            self.query_one("#checks", Static).update(  # no earlier file's word stays up
                f"adding {escape(path.name)} ...\n{self._shown}")
            self.post_message(IngestFile(path, self.position))
        event.input.value = ""

    def key_escape(self) -> None:
        """Close the entry box (keys go to the screen again); forget a held frame."""
        self.query_one("#path", Input).display = False
        self.set_focus(None)
        if self.held is not None:
            self.held = None
            self.query_one("#checks", Static).update(self._shown)
            self._look_at_card()

    def action_place_here(self) -> None:
        """Start this position again with the held frame (the earlier ones stay in raw/)."""
        if self.held is not None:
            self.post_message(IngestFile(self.held, self.position, retake=True))
            self.held = None

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
        self.notify(f"{escape(Path(frames[-1].file).name)} taken out of the {self.position} "
                    "position (the file stays in raw/)")
        if frames_at(session, self.position):
            self._recheck(session)
        else:
            self._shown = ""
            self.query_one("#checks", Static).update(self._waiting())

    def action_next(self) -> None:
        """Next step; a held frame goes along to the next position. After a failed check
        only on a second ``n``: moving on keeps a frame that will fail processing."""
        after = step_after(self.position, +1)
        if self.held is not None and after in CHECKLISTS:
            self.post_message(IngestFile(self.held, after))
            self.held = None
        elif self.failed and not self.confirm:
            self.confirm = True
            self.notify(f"the {self.position} frame failed a check ({escape(self.failed)}): "
                        "take it again, or press n again to go on anyway", severity="warning",
                        timeout=8)
            return
        super().action_next()
