"""The start screen: the sessions of the capture folder to resume, or a new one."""

from __future__ import annotations

import contextlib
from pathlib import Path

from rich.text import Text
from textual.app import ComposeResult
from textual.binding import Binding
from textual.widgets import DataTable, Footer, Input, Static

from rigkit.capture import is_session, load_session
from rigkit.capture.actions import create_session_in
from rigkit.capture.field import frames_at, resume_step
from rigkit.core.tables import visible
from rigkit.errors import RigkitError
from rigkit.tui.header import FieldHeader
from rigkit.tui.messages import OpenSession
from rigkit.tui.screens.common import FieldScreen, escape, host


class StartScreen(FieldScreen):
    """Resume a session of the capture folder, or start a new one with a rig profile."""

    AUTO_FOCUS = "#sessions"
    BINDINGS = [Binding("enter", "open", "open session", show=True)]

    def compose(self) -> ComposeResult:
        yield FieldHeader()
        yield Static("Sessions in " + escape(str(host(self).config.capture)), classes="title")
        yield DataTable(id="sessions", cursor_type="row")
        yield Static("Enter: open the selected session   Tab: start a new one below",
                     id="hint")
        yield Static("New session: NAME RIG.yaml, then Enter", classes="title")
        yield Input(placeholder="ridge-0412 rigs/p1000-tripod.yaml", id="new")
        yield Static("", id="message")
        yield Footer(compact=True)

    def on_mount(self) -> None:
        table = self.query_one(DataTable)
        table.add_columns("session", "resumes at", "frames", "targets")
        capture = host(self).config.capture
        for folder in _sessions_in(capture):  # named by folder, as on the card
            name = Text(visible(folder.name, lines=False))  # as it is, never obeyed
            try:
                session = load_session(folder)
            except RigkitError:  # opening it shows why
                table.add_row(name, "unreadable: Enter says why", "", "", key=str(folder))
                continue
            frames = sum(len(frames_at(session, p)) for p in ("left", "right", "back"))
            table.add_row(name, resume_step(session), str(frames),
                          str(len(session.targets)), key=str(folder))

    def key_escape(self) -> None:
        """Leave the new-session box: keys (q included) go to the list again."""
        self.query_one(DataTable).focus()

    def action_open(self) -> None:
        table = self.query_one(DataTable)
        if table.row_count == 0:
            return
        key = table.coordinate_to_cell_key(table.cursor_coordinate).row_key.value
        self._open(Path(str(key)))

    def on_data_table_row_selected(self, event: DataTable.RowSelected) -> None:
        self._open(Path(str(event.row_key.value)))

    def _open(self, folder: Path) -> None:
        try:
            self.post_message(OpenSession(load_session(folder)))
        except RigkitError as exc:
            self.query_one("#message", Static).update(f"[b $error]{escape(str(exc))}[/]")

    def on_input_submitted(self, event: Input.Submitted) -> None:
        parts = event.value.split()
        app = host(self)
        rig = Path(parts[1]) if len(parts) > 1 else app.config.rig
        if not parts or rig is None:
            self.query_one("#message", Static).update(
                "[b $error]give a session name and a rig profile (NAME RIG.yaml)[/]")
            return
        try:
            session = create_session_in(app.config.capture, parts[0], rig)
        except RigkitError as exc:
            self.query_one("#message", Static).update(f"[b $error]{escape(str(exc))}[/]")
            return
        self.post_message(OpenSession(session))


def _sessions_in(capture: Path) -> list[Path]:
    """The session folders in ``capture``, by name; an entry that cannot be looked at (a
    link to an unreadable tree) is left out, and a folder that cannot be listed lists
    none (opening a session by name says why)."""
    try:
        entries = sorted(capture.iterdir()) if capture.is_dir() else []
    except OSError:
        return []
    found = []
    for entry in entries:
        with contextlib.suppress(OSError):
            if is_session(entry):
                found.append(entry)
    return found
