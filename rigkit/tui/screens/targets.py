"""The targets step: mark where the laser hit on the left frame; readings arrive from
the rangefinder (or are typed in) and are saved to the session as they come."""

from __future__ import annotations

import statistics

import numpy as np
from textual import work
from textual.app import ComposeResult
from textual.binding import Binding
from textual.containers import Horizontal, Vertical
from textual.widgets import Footer, Header, Input, Static
from textual.worker import get_current_worker

from rigkit.capture import LaserReading, Session, Target, add_target, utc_now
from rigkit.capture.field import frames_at
from rigkit.capture.model import stray_readings
from rigkit.capture.readings import implied_range, reading_doubt, reading_from_device
from rigkit.capture.targets import remove_reading, remove_target
from rigkit.capture.views import check_image
from rigkit.errors import RigkitError
from rigkit.rangefinder.follow import LinkStatus, follow
from rigkit.rangefinder.ranging import parse_typed_range
from rigkit.tui.messages import SessionChanged
from rigkit.tui.screens.common import StepScreen, escape, host
from rigkit.tui.widgets import Mark, PixelView


class TargetsScreen(StepScreen):
    """Mark where the laser hit on the left frame; readings arrive and are saved."""

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
    DEMO_SHOTS = 3

    def __init__(self, session: Session) -> None:
        """``session``: the session whose targets are marked; this screen changes it."""
        super().__init__()
        self.session = session
        self.reduction = 1.0  # full-resolution px per px of the shown left view
        self.protocol = "trupulse"
        self.last_shot = ""  # what the newest shot was and where it went
        self.reading_at = -1  # the reading under the readings cursor (-1: the newest)
        self.implied_m: float | None = None  # the range the back view implied
        self.selected = session.targets[-1].name if session.targets else None
        self.confirm = ""  # the action a second key press confirms ("d T2", "n")

    def compose(self) -> ComposeResult:
        yield Header()
        with Horizontal():
            yield PixelView(cursor=True, id="aim")
            with Vertical(id="side"):
                yield Static("", id="link")
                yield Static("", id="targets")
                yield Static("", id="readings")
        yield Input(placeholder="range in metres, then Enter (Esc: cancel)", id="range")
        yield Footer(compact=True)

    def on_mount(self) -> None:
        self.query_one("#range", Input).display = False
        self._load_left()
        self._show_targets()
        app = host(self)
        port, self.protocol = app.config.port, app.config.protocol
        spec = self.session.rig().rangefinder
        if port is None and spec is not None and spec.port is not None:
            port, self.protocol = spec.port, spec.protocol
        if app.config.demo is None and port is not None:
            self._listen(port, 0)
        elif app.config.demo is None:
            self._link("no rangefinder port: type ranges with m")
        else:
            self._link("demo: mark a target (Enter), the simulated laser fires at it")

    @work(thread=True, group="aim")
    def _load_left(self) -> None:
        session = self.session
        lefts = frames_at(session, "left")
        if not lefts:  # reached with n past empty positions: nothing to aim in
            self.app.call_from_thread(self._link, "no left frame yet: press b to go back "
                                      "and take one; targets are marked in the left view")
            return
        try:
            image, reduction = check_image(session, lefts[-1])
        except RigkitError as exc:
            self.app.call_from_thread(self._link, str(exc))
            return
        self.reduction = reduction
        self.app.call_from_thread(self._show_left, image)
        self.implied_m = implied_range(session)  # what a typed range is held against

    def _show_left(self, image: np.ndarray) -> None:
        self.query_one(PixelView).set_image(image)
        self._show_targets()

    def _current(self) -> Target | None:
        """The selected target (``t`` selects the next): readings and actions go to it."""
        return next((t for t in self.session.targets if t.name == self.selected), None)

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
            lines.append(f"{mark}{target.name} ({target.pixel[0]:.0f}, {target.pixel[1]:.0f}) "
                         f"{len(ranges)}x {middle}{note}{shot}")
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
        view = self.query_one(PixelView)
        if view.cursor is None:
            return
        session = self.session
        taken = {t.name for t in session.targets}
        name = next(f"T{n}" for n in range(1, len(taken) + 2) if f"T{n}" not in taken)
        pixel = self._full(view.cursor)
        self._changed(add_target(session, name, pixel))
        self.selected, self.reading_at = name, -1
        self._show_targets()
        demo = host(self).config.demo
        if demo is not None:
            self._listen(demo.laser_url(pixel), self.DEMO_SHOTS)

    def action_select(self) -> None:
        names = [t.name for t in self.session.targets]
        if names:
            at = names.index(self.selected) if self.selected in names else -1
            self.selected = names[(at + 1) % len(names)]
            self.reading_at = -1
            self._show_targets()

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
        self._show_readings()

    def action_drop_reading(self) -> None:
        """Remove the reading under the readings cursor (the session keeps a record)."""
        target = self._current()
        if target is None or not target.readings:
            self.notify("the selected target has no reading to drop", severity="warning")
            return
        number = self.reading_at % len(target.readings) + 1
        gone = target.readings[number - 1].slope_distance_m
        self._changed(remove_reading(self.session, target.name, number))
        self.reading_at = -1
        self.notify(f"dropped {target.name}'s reading {number} ({gone:.2f} m)")
        self._show_targets()

    def _show_readings(self) -> None:
        """The selected target's readings as the session holds them, the one under the
        readings cursor marked; the newest shot above them."""
        target = self._current()
        lines = ["[b]readings[/] ([ ]: choose; x: drop)"]
        if self.last_shot:
            lines.append(escape(self.last_shot))
        if target is not None:
            at = self.reading_at % len(target.readings) if target.readings else None
            for i, reading in enumerate(target.readings):
                mark = "[b $accent]›[/]" if i == at else " "
                lines.append(f"{mark}{i + 1} {reading.slope_distance_m:8.2f} m "
                             f"{escape(reading.source.split(':', 1)[0])}")
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
        self._changed(remove_target(self.session, target.name))
        self.selected = self.session.targets[-1].name if self.session.targets else None
        self._show_targets()

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
        others = [r.slope_distance_m for r in target.readings] if target else []
        doubt = reading_doubt(value, others, self.implied_m, self.session.rig().nominal_range_m)
        if doubt and self.confirm != f"m {value:g}":
            self.confirm = f"m {value:g}"
            self.notify(f"{escape(doubt)}: a typo? press m and type it again to keep it",
                        severity="warning", timeout=10)
            return
        self.confirm = ""
        self._add_reading(LaserReading(value, utc_now(), "manual"))

    def _add_reading(self, reading: LaserReading) -> None:
        """A shot (from the laser or typed) to the selected target: the rule the targets
        list shows with "← next shot"."""
        target = self._current()
        source = reading.source.split(":", 1)[0]
        self.last_shot = (f"last shot {reading.time_utc[11:19]} "
                          f"{reading.slope_distance_m:.2f} m {source}")
        if target is None:
            self.last_shot += "  (not kept: mark a target first)"
        else:
            try:
                session = add_target(self.session, target.name, target.pixel,
                                     window_px=target.window_px, readings=[reading])
            except RigkitError as exc:
                self.notify(escape(str(exc)), severity="error")
                return
            self._changed(session)
            self.last_shot += f" -> {target.name}"
            self.reading_at = -1
        self._show_targets()

    def _changed(self, session: Session) -> None:
        """Keep the session this screen changed, and tell the app."""
        self.session = session
        self.post_message(SessionChanged(session))

    def _link(self, text: str) -> None:
        self.query_one("#link", Static).update(f"[b]laser[/] {escape(text)}")

    @work(thread=True, exclusive=True, group="laser")
    def _listen(self, url: str, count: int) -> None:
        """Readings from ``url`` until the screen closes (or ``count`` of them, if > 0)."""
        worker = get_current_worker()
        app = host(self)
        protocol = self.protocol
        got = 0
        for item in follow(url, protocol, stopped=lambda: worker.is_cancelled or app.stop.is_set()):
            if isinstance(item, LinkStatus):
                self.app.call_from_thread(self._link, item.message)
                continue
            self.app.call_from_thread(self._add_reading,
                                 reading_from_device(item, f"{protocol}:{url}"))
            got += 1
            if count and got >= count:
                self.app.call_from_thread(self._link, f"{got} shots fired; mark the next target")
                return

    def on_unmount(self) -> None:
        self.workers.cancel_group(self, "laser")
