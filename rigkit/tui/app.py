"""The field TUI's application: session state, navigation, and the background workers
that watch the card folder and ingest frames.

Every change goes through the session API (:mod:`rigkit.capture`) as it is made, so the
session folder is always up to date: quitting or a crash loses nothing, and starting
``rigkit field`` on the session again opens the step it stopped at
(:func:`rigkit.capture.field.next_step`).
"""

from __future__ import annotations

import contextlib
import sys
import threading
from pathlib import Path

from textual import work
from textual.app import App
from textual.binding import Binding
from textual.message import Message
from textual.theme import Theme

from rigkit.capture import Session, is_session, load_session, log_event
from rigkit.capture.field import (
    frames_at,
    ingest,
    newest_failed,
    onsite_checks,
    resume_note,
    resume_step,
)
from rigkit.capture.positioning import set_field_step
from rigkit.capture.views import check_image
from rigkit.core.chatter import private_terminal
from rigkit.core.tables import visible
from rigkit.errors import RigkitError, environment_message
from rigkit.tui.config import FieldConfig
from rigkit.tui.messages import (
    CheckPosition,
    FrameAdded,
    FrameChecked,
    FrameHeld,
    FrameRefused,
    Goto,
    IngestFile,
    OpenSession,
    SessionChanged,
)
from rigkit.tui.screens import (
    PositionScreen,
    ProcessScreen,
    RigScreen,
    StartScreen,
    TargetsScreen,
)
from rigkit.tui.watch import arrivals

# High contrast for sunlight: white on black, saturated accents.
FIELD_THEME = Theme(
    name="field-contrast",
    primary="#ffd700",
    secondary="#00d7ff",
    accent="#ff5fff",
    foreground="#ffffff",
    background="#000000",
    surface="#000000",
    panel="#1c1c1c",
    success="#00ff5f",
    warning="#ffaf00",
    error="#ff3030",
    dark=True,
)

def run_field(config: FieldConfig) -> int:
    """Run ``rigkit field`` in this terminal; its exit status: 0, or 1 where an error
    ended the app (which ``history.log`` then records). Textual draws on
    ``sys.__stderr__``; it gets a duplicate of the terminal of its own, so that while a
    decoder's messages are captured from descriptor 2 (:mod:`rigkit.core.chatter`) the
    screen stays."""
    terminal, saved = private_terminal(), sys.__stderr__
    setattr(sys, "__stderr__", terminal)  # noqa: B010 (the name is read-only to mypy only)
    app = FieldApp(config)
    try:
        app.run()
    finally:
        setattr(sys, "__stderr__", saved)  # noqa: B010
        terminal.close()
    return ended_by_error(app)


def ended_by_error(app: FieldApp) -> int:
    """1, with a line in the session's ``history.log``, where an exception ended ``app``;
    else its own return code (0)."""
    error = app._exception  # Textual keeps what ended the app there
    if error is None and not app.return_code:
        return 0
    session = app.session.path if app.session is not None else app.config.session
    if session is not None and is_session(session):
        with contextlib.suppress(OSError, RigkitError):
            log_event(session, "field", f"stopped by an internal error: "
                      f"{type(error).__name__}: {error}; please report it")
    return 1


class FieldApp(App[None]):
    """``rigkit field``: the guided three-position capture. Holds the session and runs
    the frame workers (arrivals, ingest, checks); the screens (:mod:`rigkit.tui.screens`)
    show steps, run their own step's long work (processing, export, the laser) and post
    what changed or what the user asks for (:mod:`rigkit.tui.messages`)."""

    TITLE = "rigkit field"
    CSS_PATH = "field.tcss"
    BINDINGS = [Binding("q", "quit_field", "quit", priority=False)]
    ENABLE_COMMAND_PALETTE = False
    AUTO_FOCUS = None  # keys go to the screen; an entry box takes focus when opened

    def __init__(self, config: FieldConfig) -> None:
        super().__init__()
        self.config = config
        self.session: Session | None = None
        self.stop = threading.Event()

    # -- start and navigation -----------------------------------------------------------

    def on_mount(self) -> None:
        self.register_theme(FIELD_THEME)
        self.theme = FIELD_THEME.name
        watch = self.config.demo.card if self.config.demo else self.config.watch
        if watch is not None:
            self.watch_folder(watch)
        if self.config.session is not None:
            self.open_session(load_session(self.config.session))
        else:
            self.push_screen(StartScreen())

    def open_session(self, session: Session) -> None:
        """Show ``session`` at the step it stopped at (:func:`resume_step`; where
        session.yaml names a step this rigkit does not know, saying so)."""
        self.session = session
        self.sub_title = session.name
        self.goto(resume_step(session), resume=True)
        note = resume_note(session)
        if note:
            self.notify(visible(note, lines=False), severity="warning", timeout=15,
                        markup=False)

    def goto(self, step: str, resume: bool = False) -> None:
        """Replace the current step's screen with ``step``'s (``resume``: opening a
        session, so the process step shows its latest run rather than running again)."""
        assert self.session is not None
        screen = (
            RigScreen() if step == "rig"
            else TargetsScreen(self.session) if step == "targets"
            else ProcessScreen(resume) if step == "process"
            else PositionScreen(step)
        )
        if len(self.screen_stack) > 1:
            self.switch_screen(screen)
        else:
            self.push_screen(screen)
        self.remember_step(self.session.path, step)

    @work(thread=True, group="step")
    def remember_step(self, session: Path, step: str) -> None:
        """Record ``step`` in the session, where ``rigkit field`` resumes it."""
        try:
            set_field_step(session, step)
        except (RigkitError, OSError) as exc:
            message = str(exc) if isinstance(exc, RigkitError) else environment_message(exc)
            self.warn(f"where the capture stands was not saved: {visible(message)}")

    def on_goto(self, message: Goto) -> None:
        self.goto(message.step, message.resume)

    def on_open_session(self, message: OpenSession) -> None:
        self.open_session(message.session)

    def on_session_changed(self, message: SessionChanged) -> None:
        self.session = message.session

    def action_quit_field(self) -> None:
        """Quit: everything is already saved; stop the watcher and the workers."""
        self.stop.set()
        self.exit()

    def on_unmount(self) -> None:
        self.stop.set()

    # -- frames ---------------------------------------------------------------------------

    @work(thread=True, group="watch")
    def watch_folder(self, folder: Path) -> None:
        """Ingest each frame that arrives in ``folder`` into the position on screen; when
        the folder goes away (card removed), wait for it to come back. Nothing on the
        card ends the app: what cannot be watched is said and skipped
        (:func:`rigkit.tui.watch.arrivals`)."""
        while not self.stop.is_set():
            if folder.is_dir():
                try:
                    for path in arrivals(folder, self.stop, self.config.settle_s, self.warn):
                        self.arrived(path)
                except (OSError, RigkitError) as exc:
                    self.warn(f"watching {visible(str(folder), lines=False)}: "
                              f"{visible(str(exc), lines=False)}; watching again")
                else:
                    if not self.stop.is_set():
                        self.warn(f"{visible(str(folder), lines=False)} is gone (card "
                                  "removed?); watching again when it is back")
            self.stop.wait(1.0)

    def warn(self, line: str) -> None:
        """``line`` (shown as it is, never read as markup) as a warning (from a worker)."""
        self.call_from_thread(self.notify, line, severity="warning", markup=False)

    def arrived(self, path: Path) -> None:
        """A complete new file in the watched folder (in the watcher's thread)."""
        position = self.call_from_thread(self.current_position)
        if position is None:
            self.warn(f"{visible(path.name, lines=False)} arrived; open a position to add it")
        else:
            self.ingest(path, position)

    def current_position(self) -> str | None:
        screen = self.screen
        return screen.position if isinstance(screen, PositionScreen) else None

    def on_ingest_file(self, message: IngestFile) -> None:
        self.ingest_file(message.path, message.position, message.retake)

    @work(thread=True, group="ingest")
    def ingest_file(self, path: Path, position: str, retake: bool = False) -> None:
        """A file named by hand (the path entry) or placed by the operator, ingested
        like an arrival."""
        self.ingest(path, position, retake)

    def ingest(self, path: Path, position: str, retake: bool = False) -> None:
        """Copy ``path`` into the session for ``position``, then run its on-site checks
        (blocking; called from worker threads): staged, hashed and decoded once
        (:func:`rigkit.capture.field.ingest`; what is refused at a glance is told before
        it is read whole). A frame that does not match the position's burst is held back
        with a question instead (unless ``retake``)."""
        assert self.session is not None
        retake = retake or newest_failed(self.session, position)  # a retake joins no burst
        try:
            done = ingest(self.session, position, path, replace_existing=retake,
                          burst=not retake, check_burst=not retake)
        except RigkitError as exc:
            self.tell(FrameRefused(position, str(exc)))
            return
        except OSError as exc:  # a full card or disk, a read-only session
            self.tell(FrameRefused(position, environment_message(exc)))
            return
        if done.held is not None:
            self.tell(FrameHeld(position, path, done.held))
            return
        session = done.session
        self.call_from_thread(setattr, self, "session", session)
        self.tell(FrameAdded(position, path.name))
        self.check_position(session, position)

    def on_check_position(self, message: CheckPosition) -> None:
        assert self.session is not None
        self.check_worker(self.session, message.position)

    @work(thread=True, group="check")
    def check_worker(self, session: Session, position: str) -> None:
        self.check_position(session, position)

    def check_position(self, session: Session, position: str) -> None:
        """Run the on-site checks of ``position``'s newest frame and show them (blocking)."""
        try:
            checks = onsite_checks(session, position)
            image, _ = check_image(session, frames_at(session, position)[-1])
        except RigkitError as exc:
            self.tell(FrameRefused(position, str(exc)))
            return
        self.tell(FrameChecked(position, checks, image))

    def tell(self, message: Message) -> None:
        """Post ``message`` to the screen on show (from a worker thread)."""
        self.call_from_thread(lambda: self.screen.post_message(message))
