"""The targets step: mark where the laser hit on the left frame; shots arrive from the
rangefinder the app follows (or are typed in) and are saved to the selected target."""

from __future__ import annotations

import statistics

import numpy as np
from textual import work
from textual.app import ComposeResult
from textual.binding import Binding
from textual.containers import Horizontal, Vertical
from textual.widgets import Footer, Input, Static

from rigkit.capture import Session, Target, add_target
from rigkit.capture.field import frames_at
from rigkit.capture.model import stray_readings
from rigkit.capture.readings import implied_range, next_target_name, reading_doubt
from rigkit.capture.targets import remove_reading, remove_target
from rigkit.capture.views import check_image
from rigkit.errors import RigkitError
from rigkit.rangefinder.ranging import parse_typed_range
from rigkit.tui.header import FieldHeader
from rigkit.tui.messages import (
    AimDemo,
    LaserChanged,
    SessionChanged,
    TargetSelected,
    TypedReading,
)
from rigkit.tui.screens.common import LaserLine, StepScreen, escape, host, session_of
from rigkit.tui.widgets import Mark, PixelView


class TargetsScreen(StepScreen):
    """Mark where the laser hit on the left frame; shots go to the selected target."""

    step = "targets"
    BINDINGS = [
        Binding("left", "move(-1, 0)", "aim", key_display="←↑↓→"),
        Binding("enter", "mark", "mark"),
        Binding("plus,equals_sign", "zoom(1)", show=False),  # the targets panel says it
        Binding("minus", "zoom(-1)", show=False),
        Binding("t", "select", "select"),
        Binding("m", "manual", "range"),
        Binding("left_square_bracket", "reading(-1)", show=False),  # the panel says it
        Binding("right_square_bracket", "reading(1)", show=False),
        Binding("x", "drop_reading", "drop"),
        Binding("d", "drop_target", show=False),
        Binding("up", "move(0, -1)", show=False),
        Binding("down", "move(0, 1)", show=False),
        Binding("right", "move(1, 0)", show=False),
        Binding("shift+up", "move(0, -8)", show=False),
        Binding("shift+down", "move(0, 8)", show=False),
        Binding("shift+left", "move(-8, 0)", show=False),
        Binding("shift+right", "move(8, 0)", show=False),
    ]

    def __init__(self) -> None:
        super().__init__()
        self.reduction = 1.0  # full-resolution px per px of the shown left view
        self.reading_at = -1  # the reading under the readings cursor (-1: the newest)
        self.implied_m: float | None = None  # the range the back view implied
        self.confirm = ""  # the action a second key press confirms ("d T2", "x T1 2", "n")

    @property
    def session(self) -> Session:
        """The session as the app holds it (every change lands there)."""
        return session_of(self)

    @property
    def selected(self) -> str | None:
        """The target the next shot goes to (the app's: shots arrive on any screen)."""
        return host(self).laser.selected

    def compose(self) -> ComposeResult:
        yield FieldHeader()
        with Horizontal():
            yield PixelView(cursor=True, id="aim")
            with Vertical(id="side"):
                yield Static("", id="note")
                yield Static("", id="targets")
                yield Static("", id="readings")
        yield Input(placeholder="range in metres, then Enter (Esc: cancel)", id="range")
        yield LaserLine(always=True)
        yield Footer(compact=True)

    def on_mount(self) -> None:
        self.query_one("#range", Input).display = False
        self.query_one("#note", Static).display = False
        self._load_left()
        self._show_targets()

    @work(thread=True, exclusive=True, group="aim")
    def _load_left(self) -> None:
        session = self.session
        lefts = frames_at(session, "left")
        if not lefts:  # reached with n past empty positions: nothing to aim in
            self.deliver(self._note, "no left frame yet: press b to go back and take one; "
                         "targets are marked in the left view")
            return
        try:
            image, reduction = check_image(session, lefts[-1])
        except RigkitError as exc:
            self.deliver(self._note, str(exc))
            return
        self.deliver(self._show_left, image, reduction)
        self.deliver(setattr, self, "implied_m", implied_range(session))  # typed ranges' check

    def _note(self, text: str) -> None:
        note = self.query_one("#note", Static)
        note.display = bool(text)
        note.update(f"[b $warning]{escape(text)}[/]")

    def _show_left(self, image: np.ndarray, reduction: float) -> None:
        self.reduction = reduction
        self.query_one(PixelView).set_image(image)
        self._show_targets()

    def _current(self) -> Target | None:
        """The selected target (``t`` selects the next): readings and actions go to it."""
        return next((t for t in self.session.targets if t.name == self.selected), None)

    def on_laser_changed(self, message: LaserChanged) -> None:
        self._show_targets()

    def _show_targets(self) -> None:
        session = self.session
        lines = ["[b]targets[/] (Enter: mark; +-: zoom; t: choose where the next shot goes; "
                 "m: type its range; d: delete)"]
        for target in session.targets:
            ranges = [r.slope_distance_m for r in target.readings]
            middle = f"{statistics.median(ranges):.2f} m" if ranges else "no reading"
            strays = len(stray_readings(target))
            note = f" [b $warning]{strays} stray[/]" if strays else ""
            chosen = target.name == self.selected
            mark = "[b $accent]›[/]" if chosen else " "
            shot = "  [b $accent]← next shot[/]" if chosen else ""
            lines.append(f"{mark}{escape(target.name)} ({target.pixel[0]:.0f}, "
                         f"{target.pixel[1]:.0f}) {len(ranges)}x {middle}{note}{shot}")
        view = self.query_one(PixelView)
        if view.cursor is not None:
            u, v = self._full(view.cursor)
            lines.append(f"cursor ({u:.0f}, {v:.0f})  zoom {view.zoom}x")
        self.query_one("#targets", Static).update("\n".join(lines))
        self._show_readings()
        scale = self.reduction
        view.set_marks([Mark((t.pixel[0] + 0.5) / scale - 0.5, (t.pixel[1] + 0.5) / scale - 0.5,
                             t.name) for t in session.targets])

    def _full(self, cursor: tuple[int, int]) -> tuple[float, float]:
        """A check-image pixel in the full-resolution left frame (centres at integers)."""
        scale = self.reduction
        return (cursor[0] + 0.5) * scale - 0.5, (cursor[1] + 0.5) * scale - 0.5

    def action_move(self, du: int, dv: int) -> None:
        self.query_one(PixelView).move_cursor(du, dv)
        self._show_targets()

    def action_zoom(self, steps: int) -> None:
        self.query_one(PixelView).change_zoom(steps)
        self._show_targets()

    def action_mark(self) -> None:
        """A new target at the cursor, selected: the next shots go to it."""
        view = self.query_one(PixelView)
        if view.cursor is None:
            return
        name = next_target_name(self.session)  # never a deleted target's name again
        pixel = self._full(view.cursor)
        try:
            self._changed(add_target(self.session, name, pixel))
        except RigkitError as exc:
            self.notify(str(exc), severity="error")
            return
        self._select(name)
        demo = host(self).config.demo
        if demo is None:
            return
        blind = demo.no_depth(pixel)
        if blind:  # the demo's laser fires only where the depth map will have depth
            self.notify(f"demo: {name} is {blind}: no depth will be estimated there; mark "
                        "a spot on the ridge or the buildings (d deletes it)",
                        severity="warning", timeout=10)
        else:
            self.post_message(AimDemo(pixel))

    def _select(self, name: str | None) -> None:
        """Shots go to ``name`` from now on; the app saves those held to it."""
        self.reading_at = -1
        self.confirm = ""
        desk = host(self).laser
        with desk.lock:
            desk.selected = name
        self.post_message(TargetSelected())
        self._show_targets()

    def action_select(self) -> None:
        names = [t.name for t in self.session.targets]
        if names:
            at = names.index(self.selected) if self.selected in names else -1
            self._select(names[(at + 1) % len(names)])

    def action_manual(self) -> None:
        target = self._current()
        if target is None:
            self.notify("mark a target first (Enter at the cursor)", severity="warning")
            return
        entry = self.query_one("#range", Input)
        entry.placeholder = f"range to {target.name} in metres, then Enter (Esc: cancel)"
        entry.display = True
        entry.focus()

    def action_reading(self, step: int) -> None:
        """Move the readings cursor through the selected target's readings."""
        target = self._current()
        if target is None or not target.readings:
            return
        at = self.reading_at % len(target.readings)
        self.reading_at = min(max(at + step, 0), len(target.readings) - 1)
        self.confirm = ""
        self._show_readings()

    def action_drop_reading(self) -> None:
        """Remove the reading under the readings cursor once ``x`` is pressed a second
        time for it, as frames and targets are dropped (the session keeps a record)."""
        target = self._current()
        if target is None or not target.readings:
            self.notify("the selected target has no reading to drop", severity="warning")
            return
        number = self.reading_at % len(target.readings) + 1
        gone = target.readings[number - 1].slope_distance_m
        if self.confirm != f"x {target.name} {number} {gone}":
            self.confirm = f"x {target.name} {number} {gone}"
            self.notify(f"press x again to drop {target.name}'s reading {number} "
                        f"({gone:.2f} m)", severity="warning", timeout=8)
            return
        self.confirm = ""
        try:
            self._changed(remove_reading(self.session, target.name, number))
        except RigkitError as exc:
            self.notify(str(exc), severity="error")
            return
        self.reading_at = -1
        self.notify(f"dropped {target.name}'s reading {number} ({gone:.2f} m)")
        self._show_targets()

    def _show_readings(self) -> None:
        """The selected target's readings as the session holds them, the one under the
        readings cursor marked, strays said; the shots not saved yet above them."""
        target = self._current()
        lines = ["[b]readings[/] ([ ]: choose; x: drop)"]
        held = host(self).laser.held()
        if held:
            lines.append(f"[b $warning]{len(held)} shot(s) not saved yet[/]")
        if target is not None:
            at = self.reading_at % len(target.readings) if target.readings else None
            strays = stray_readings(target)
            for i, reading in enumerate(target.readings):
                mark = "[b $accent]›[/]" if i == at else " "
                stray = " [b $warning]stray[/]" if i in strays else ""
                lines.append(f"{mark}{i + 1} {reading.slope_distance_m:8.2f} m "
                             f"{escape(reading.source.split(':', 1)[0])}{stray}")
        self.query_one("#readings", Static).update("\n".join(lines))

    def action_drop_target(self) -> None:
        """Remove the selected target, once ``d`` is pressed a second time."""
        target = self._current()
        if target is None:
            return
        if self.confirm != f"d {target.name}":
            self.confirm = f"d {target.name}"
            self.notify(f"press d again to drop {target.name} and its "
                        f"{len(target.readings)} reading(s)", severity="warning")
            return
        self.confirm = ""
        try:
            session = remove_target(self.session, target.name)
        except RigkitError as exc:
            self.notify(str(exc), severity="error")
            return
        self._changed(session)
        self._select(session.targets[-1].name if session.targets else None)

    def action_next(self) -> None:
        """On to processing; without a single reading, only once ``n`` is pressed again."""
        if any(t.readings for t in self.session.targets) or self.confirm == "n":
            self.confirm = ""
            super().action_next()
            return
        self.confirm = "n"
        self.notify("no target has a laser reading, so nothing will check the depth: mark "
                    "one (Enter) and fire at it, or press n again to go on without",
                    severity="warning", timeout=8)

    def key_escape(self) -> None:
        """Close the entry box; keys go to the screen again."""
        self.query_one("#range", Input).display = False
        self.set_focus(None)

    def on_input_submitted(self, event: Input.Submitted) -> None:
        self.key_escape()
        text, event.input.value = event.value.strip(), ""
        try:
            value = parse_typed_range(text, self.session.rig())
        except RigkitError as exc:
            self.notify(escape(str(exc)), severity="error")
            return
        target = self._current()
        if target is None:
            return
        others = [r.slope_distance_m for r in target.readings]
        doubt = reading_doubt(value, others, self.implied_m, self.session.rig().nominal_range_m)
        if doubt and self.confirm != f"m {target.name} {value:g}":
            self.confirm = f"m {target.name} {value:g}"
            self.notify(f"{escape(doubt)}: a typo? press m and type it again to keep it",
                        severity="warning", timeout=10)
            return
        self.confirm = ""
        self.reading_at = -1
        self.post_message(TypedReading(value))

    def _changed(self, session: Session) -> None:
        """Keep the session as this change saved it, and tell the app (which reads it
        again from the folder, where the workers' changes land too)."""
        host(self).session = session
        self.post_message(SessionChanged(session))
