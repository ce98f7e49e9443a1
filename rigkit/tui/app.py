"""The field TUI's application: session state, navigation, and the background workers
that watch the card folder, ingest and check frames, and follow the laser.

Every change goes through the session API (:mod:`rigkit.capture`) as it is made, so the
session folder is always up to date: quitting or a crash loses nothing, and starting
``rigkit field`` on the session again opens the step it stopped at
(:func:`rigkit.capture.field.resume_step`).

The first screen shows before the heavy libraries are imported (the pipeline, OpenCV,
the screens that use them; the demo's scene is rendered then too): a light screen says
what is being opened while a worker imports them, and the session's step replaces it.
"""

from __future__ import annotations

import contextlib
import importlib
import queue
import sys
import threading
import time
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

from textual import work
from textual.app import App, ComposeResult
from textual.binding import Binding
from textual.message import Message
from textual.screen import Screen
from textual.theme import Theme
from textual.widgets import Footer, Static
from textual.worker import get_current_worker

from rigkit.capture.model import POSITIONS, Session
from rigkit.capture.session import is_session, load_session, log_event
from rigkit.core.chatter import private_terminal
from rigkit.core.tables import visible
from rigkit.errors import InputError, RigkitError, environment_message
from rigkit.tui.config import FieldConfig
from rigkit.tui.header import FieldHeader
from rigkit.tui.laser import LaserDesk, Shot
from rigkit.tui.messages import (
    AimDemo,
    CheckPosition,
    FrameAdded,
    FrameArrived,
    FrameChecked,
    FrameHeld,
    FrameRefused,
    Goto,
    IngestFile,
    LaserChanged,
    OpenSession,
    SessionChanged,
    TargetSelected,
    Tidings,
    TypedReading,
)

if TYPE_CHECKING:
    from rigkit.capture import LaserReading
    from rigkit.rangefinder.follow import LinkStatus

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
HEAVY = ("rigkit.tui.screens", "rigkit.capture.field", "rigkit.capture.actions")
"""What the app imports after its first screen shows (OpenCV, the pipeline, the
screens' libraries)."""
DEMO_SHOTS = 3
"""Shots the demo's simulated laser fires at each target marked."""
BUSY_RETRY_S = 1.0
"""Wait before a shot is offered to a busy session again (processing holds its lock)."""


def run_field(config: FieldConfig) -> int:
    """Run ``rigkit field`` in this terminal; its exit status: 0, or 1 where an error
    ended the app (which ``history.log`` then records). Textual draws on
    ``sys.__stderr__``; it gets a duplicate of the terminal of its own, so that while a
    decoder's messages are captured from descriptor 2 (:mod:`rigkit.core.chatter`) the
    screen stays."""
    # textual-image asks the terminal what it can draw when it is imported: here, before
    # the app reads the terminal's input (imported by a worker once the app runs, the
    # answer went to the app and the import waited for ever; :mod:`rigkit.tui.previews`).
    importlib.import_module("textual_image.renderable")
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


class OpeningScreen(Screen[None]):
    """The first screen, shown at once: what is being opened, while the libraries load
    (and the demo's scene renders)."""

    def compose(self) -> ComposeResult:
        yield FieldHeader()
        yield Static("starting ...", id="opening")
        yield Footer(compact=True)

    def say(self, text: str) -> None:
        self.query_one("#opening", Static).update(text)


# -- what the app's workers tell the app (on its own thread) ---------------------------------


class Loaded(Message):
    """The heavy imports are done (and the demo prepared): open the session. ``error``:
    one line where it could not be (the app then says it and waits for q)."""

    def __init__(self, error: str = "") -> None:
        super().__init__()
        self.error = error


class Arrival(Message):
    """A complete new file in the watched folder."""

    def __init__(self, path: Path) -> None:
        super().__init__()
        self.path = path


class Reread(Message):
    """The session as its folder held it once change number ``change`` was made."""

    def __init__(self, session: Session, change: int) -> None:
        super().__init__()
        self.session, self.change = session, change


class Forward(Message):
    """``tidings`` for the screen on show."""

    def __init__(self, tidings: Tidings) -> None:
        super().__init__()
        self.tidings = tidings


class LinkNews(Message):
    """From the laser's worker: a reading (as the session records it) or the link's
    state."""

    def __init__(self, news: LaserReading | LinkStatus) -> None:
        super().__init__()
        self.news = news


class Notice(Message):
    """A line for the operator from a worker (``severity`` as Textual's notify)."""

    def __init__(self, text: str, severity: str = "information") -> None:
        super().__init__()
        self.text, self.severity = text, severity


@dataclass(frozen=True)
class FrameJob:
    """One piece of frame work, done in arrival order: a file to add to ``position``
    (``retake``: in place of its frames), or with ``path`` None, the checks of its
    newest frame to show again."""

    position: str
    path: Path | None = None
    retake: bool = False


class FieldApp(App[None]):
    """``rigkit field``: the guided three-position capture. Holds the session, the
    step on show, the laser (:class:`rigkit.tui.laser.LaserDesk`) and the frame
    workers (arrivals, ingest, checks, one frame at a time in arrival order); the
    screens (:mod:`rigkit.tui.screens`) show steps, run their own step's long work
    (processing, export) and post what changed or what the user asks for
    (:mod:`rigkit.tui.messages`)."""

    TITLE = "rigkit field"
    CSS_PATH = "field.tcss"
    BINDINGS = [
        Binding("q", "quit_field", "quit", priority=False),
        Binding("ctrl+c", "quit_field", show=False, priority=True),  # as q, never a hint
        Binding("ctrl+q", "quit_field", show=False, priority=True),
    ]
    ENABLE_COMMAND_PALETTE = False
    AUTO_FOCUS = None  # keys go to the screen; an entry box takes focus when opened

    def __init__(self, config: FieldConfig) -> None:
        super().__init__()
        self.config = config
        self.session: Session | None = None
        self.stop = threading.Event()
        self.step: str | None = None
        self.laser = LaserDesk("no rangefinder port: type ranges with m (targets step)", None)
        self.processing = threading.Lock()  # one processing run at a time
        self.outcomes: dict[str, tuple[object, FrameChecked]] = {}  # each position's last
        self._frames: queue.Queue[FrameJob] = queue.Queue()
        self._queued: list[FrameJob] = []  # what the frame worker has yet to finish
        self._taken: dict[Path, int] = {}  # files added this run, and their sizes
        self._step_lock = threading.Lock()
        self._step_saved: str | None = None
        self._quitting = False
        self._changes = 0  # changes to the session told to the app

    # -- start ----------------------------------------------------------------------------

    def on_mount(self) -> None:
        self.register_theme(FIELD_THEME)
        self.theme = FIELD_THEME.name
        if self.config.session is not None:  # (set before the first header shows)
            self.sub_title = self.config.session.name
        self.push_screen(OpeningScreen())
        self._prepare()

    @work(thread=True, group="prepare")
    def _prepare(self) -> None:
        """Import what the steps need, and prepare the demo, off the screen's thread."""
        from rigkit.core.lazy import preload

        self.post_message(Notice("loading ..."))
        for module in HEAVY:
            importlib.import_module(module)
        preload("scipy.optimize")  # the checks' fits: imported while the step opens
        demo = self.config.demo
        try:
            if demo is not None:
                demo.prepare(self._say)
            if self.config.session is not None:
                load_session(self.config.session)
        except RigkitError as exc:
            self.post_message(Loaded(str(exc)))
            return
        except OSError as exc:
            self.post_message(Loaded(environment_message(exc)))
            return
        self.post_message(Loaded())

    def _say(self, text: str) -> None:
        """From a worker: ``text`` on the first screen (or as a notification)."""
        self.post_message(Notice(text))

    def on_loaded(self, message: Loaded) -> None:
        if message.error:
            self._opening(f"[b $error]✘ {visible(message.error, markup=True)}[/]\nq: quit")
            return
        from rigkit.tui.screens import StartScreen

        watch = self.config.demo.card if self.config.demo else self.config.watch
        if watch is not None:
            self.watch_folder(watch)
        self.frame_worker()
        if self.config.session is not None:
            self.open_session(load_session(self.config.session))
        else:
            self.switch_screen(StartScreen())

    def _opening(self, text: str) -> None:
        if self.screen_stack and isinstance(self.screen, OpeningScreen):
            self.screen.say(text)

    def on_notice(self, message: Notice) -> None:
        if not self.screen_stack:
            return
        if isinstance(self.screen, OpeningScreen):
            self.screen.say(visible(message.text, markup=True))
        else:
            self.notify(visible(message.text), severity=message.severity,  # type: ignore[arg-type]
                        markup=False)

    # -- navigation -------------------------------------------------------------------------

    def open_session(self, session: Session) -> None:
        """Show ``session`` at the step it stopped at (:func:`resume_step`; where
        session.yaml names a step this rigkit does not know, saying so), and follow its
        laser."""
        from rigkit.capture.field import resume_note, resume_step

        self.session = session
        if self.sub_title != session.name:
            self.sub_title = session.name
        self.laser.selected = session.targets[-1].name if session.targets else None
        self._start_laser(session)
        self.goto(resume_step(session), resume=True)
        note = resume_note(session)
        if note:
            self.notify(visible(note, lines=False), severity="warning", timeout=15,
                        markup=False)

    def goto(self, step: str, resume: bool = False) -> None:
        """Replace the step on show with ``step``'s screen (``resume``: opening a
        session, so the process step shows its latest run rather than running again)."""
        from rigkit.tui.screens import PositionScreen, ProcessScreen, RigScreen, TargetsScreen

        assert self.session is not None
        self.step = step
        screen = (
            RigScreen() if step == "rig"
            else TargetsScreen() if step == "targets"
            else ProcessScreen(resume) if step == "process"
            else PositionScreen(step)
        )
        self.switch_screen(screen)
        self.remember_step()

    @work(thread=True, group="step")
    def remember_step(self) -> None:
        """Record the step on show in the session, off the screen's thread."""
        self._save_step()

    def _save_step(self) -> None:
        """Record the step on show in the session, where ``rigkit field`` resumes it:
        one writer at a time, each writing the newest step (keys pressed quickly never
        leave an older step recorded last)."""
        from rigkit.capture.positioning import set_field_step

        with self._step_lock:
            step, session = self.step, self.session
            if step is None or session is None or step == self._step_saved:
                return
            try:
                set_field_step(session.path, step)
            except (RigkitError, OSError) as exc:
                text = str(exc) if isinstance(exc, RigkitError) else environment_message(exc)
                self.post_message(Notice(f"where the capture stands was not saved: {text}",
                                         "warning"))
                return
            self._step_saved = step

    def on_goto(self, message: Goto) -> None:
        self.goto(message.step, message.resume)

    def on_open_session(self, message: OpenSession) -> None:
        self.open_session(message.session)

    def on_session_changed(self, message: SessionChanged) -> None:
        """Keep the session as the change saved it, and read it again from its folder
        (changes land there from the screens and the workers in any order, and the
        folder has them all) off the screen's thread: a long ``session.yaml`` takes a
        tenth of a second to read."""
        self.session = message.session
        self._changes += 1
        self.reread(self._changes)
        self._tell(LaserChanged())

    @work(thread=True, group="reread")
    def reread(self, change: int) -> None:
        try:
            session = load_session(self._session_path())
        except RigkitError:
            return
        self.post_message(Reread(session, change))

    def on_reread(self, message: Reread) -> None:
        """The session as the folder had it after change ``message.change``: kept only
        where no change came after it (that one's reading follows)."""
        if message.change == self._changes:
            self.session = message.session
            self._tell(LaserChanged())

    def action_quit_field(self) -> None:
        """Quit: everything is already saved; shots still held are written to
        ``history.log`` (asked first); the watcher and the workers stop."""
        held = self.laser.held()
        if held and not self._quitting:
            self._quitting = True
            self.notify(f"{len(held)} laser shot(s) not saved to a target yet: press q again "
                        "to quit (they are written to history.log)", severity="warning",
                        timeout=8)
            return
        self._log_held()
        self.stop.set()
        self.exit()

    def _log_held(self) -> None:
        session = self.session
        if session is None:
            return
        for shot in self.laser.held():
            r = shot.reading
            with contextlib.suppress(OSError, RigkitError):
                log_event(session.path, "field", f"laser reading {r.slope_distance_m:.2f} m "
                          f"({r.source}, {r.time_utc}) held, not saved to a target: no "
                          "target was selected")

    def on_unmount(self) -> None:
        """Stop the workers, and record the step on show before the app goes: a quit
        pressed just after a step opened never leaves the step before it recorded (the
        lock waits for a write under way)."""
        self.stop.set()
        self._save_step()

    # -- the laser ----------------------------------------------------------------------------

    def _start_laser(self, session: Session) -> None:
        """Follow the session's rangefinder for as long as the app runs (the demo's
        simulated one fires when a target is marked)."""
        if self.config.demo is not None:
            self.laser.link = "demo: mark a target (Enter on the targets step); it fires there"
            self.laser.followed = True
            return
        port, protocol = self.config.port, self.config.protocol
        spec = session.rig().rangefinder
        if port is None and spec is not None and spec.port is not None:
            port, protocol = spec.port, spec.protocol
        if port is not None:
            self.laser.link, self.laser.followed = f"opening {port} ...", True
            self.follow_laser(port, protocol, 0)

    @work(thread=True, exclusive=True, group="laser")
    def follow_laser(self, url: str, protocol: str, count: int) -> None:
        """Readings from ``url`` until the app ends (or ``count`` of them, if > 0)."""
        from rigkit.capture.readings import reading_from_device
        from rigkit.rangefinder.follow import LinkStatus, follow

        worker = get_current_worker()
        got = 0
        for item in follow(url, protocol,
                           stopped=lambda: worker.is_cancelled or self.stop.is_set()):
            if isinstance(item, LinkStatus):
                self.post_message(LinkNews(item))
                continue
            self.post_message(LinkNews(reading_from_device(item, f"{protocol}:{url}")))
            got += 1
            if count and got >= count:
                return

    def on_link_news(self, message: LinkNews) -> None:
        from rigkit.rangefinder.follow import LinkStatus

        news = message.news
        if isinstance(news, LinkStatus):
            with self.laser.lock:
                self.laser.link, self.laser.connected = news.message, news.connected
        else:
            self.laser.take(Shot(news))
            self.file_shots_now()
        self._tell(LaserChanged())

    def on_typed_reading(self, message: TypedReading) -> None:
        from rigkit.capture import LaserReading, utc_now

        target = self.laser.selected
        self.laser.take(Shot(LaserReading(message.range_m, utc_now(), "manual"), target))
        self.file_shots_now()
        self._tell(LaserChanged())

    def on_aim_demo(self, message: AimDemo) -> None:
        demo = self.config.demo
        if demo is not None:
            self.follow_laser(demo.laser_url(message.pixel), "trupulse", DEMO_SHOTS)

    def on_target_selected(self, message: TargetSelected) -> None:
        """Shots go to the target selected now, those held first."""
        self.file_shots_now()
        self._tell(LaserChanged())

    def file_shots_now(self) -> None:
        if self.laser.start_filing():
            self.file_shots()

    @work(thread=True, group="file-shots")
    def file_shots(self) -> None:
        """Save the held shots to their targets, oldest first, each under the session's
        lock; while processing holds it they wait (said on every screen), never
        dropped."""
        from rigkit.capture import add_target

        desk = self.laser
        while (job := desk.next_to_file()) is not None:
            shot, name = job
            session = self.session
            assert session is not None
            try:
                target = session.target(name)  # a target's pixel never changes
                saved = add_target(session, name, target.pixel, window_px=target.window_px,
                                   readings=[shot.reading])
            except InputError as exc:
                if self.stop.wait(BUSY_RETRY_S if "busy" in str(exc) else 0.0):
                    return
                if "busy" not in str(exc):
                    self._not_filed(shot, name, str(exc))
                continue
            except (RigkitError, OSError) as exc:
                text = str(exc) if isinstance(exc, RigkitError) else environment_message(exc)
                self._not_filed(shot, name, text)
                continue
            desk.filed(shot, name)
            self.post_message(SessionChanged(saved))

    def _not_filed(self, shot: Shot, target: str, why: str) -> None:
        """A shot the session refuses (a range beyond the rangefinder's, a target gone):
        recorded in ``history.log`` and said, not kept held for ever."""
        desk, session, r = self.laser, self.session, shot.reading
        if session is not None:
            with contextlib.suppress(OSError, RigkitError):
                log_event(session.path, "field", f"laser reading {r.slope_distance_m:.2f} m "
                          f"({r.source}, {r.time_utc}) not saved to {target}: {why}")
        with desk.lock:
            if desk.selected == target and shot.target is None:
                desk.selected = None  # e.g. the target was deleted meanwhile: ask again
                return
        desk.filed(shot, target)
        self.post_message(Notice(f"reading {r.slope_distance_m:.2f} m not saved ({why}); "
                                 "history.log keeps it", "error"))

    # -- frames -----------------------------------------------------------------------------

    @work(thread=True, group="watch")
    def watch_folder(self, folder: Path) -> None:
        """Tell the app of each frame that arrives in ``folder``; when the folder goes
        away (card removed), wait for it to come back. Nothing on the card ends the app:
        what cannot be watched is said and skipped (:func:`rigkit.tui.watch.arrivals`)."""
        from rigkit.tui.watch import arrivals

        while not self.stop.is_set():
            if folder.is_dir():
                try:
                    for path in arrivals(folder, self.stop, self.config.settle_s, self._warn):
                        self.post_message(Arrival(path))
                except (OSError, RigkitError) as exc:
                    self._warn(f"watching {folder}: {exc}; watching again")
                else:
                    if not self.stop.is_set():
                        self._warn(f"{folder} is gone (card removed?); watching again "
                                   "when it is back")
            self.stop.wait(1.0)

    def _warn(self, line: str) -> None:
        """From a worker: ``line`` as a warning."""
        self.post_message(Notice(line, "warning"))

    def on_arrival(self, message: Arrival) -> None:
        """A frame landed: it is for the position on show when it landed."""
        path = message.path
        position = self.current_position()
        if position is None:
            self.notify(f"{visible(path.name, lines=False)} arrived; open a position to add "
                        "it (it stays on the card)", severity="warning", markup=False)
        elif not self._added_before(path):
            self.enqueue(FrameJob(position, path))

    def current_position(self) -> str | None:
        """The position whose screen is on show, if one is."""
        position = getattr(self.screen, "position", None) if self.screen_stack else None
        return position if isinstance(position, str) else None

    def _added_before(self, path: Path) -> bool:
        """Whether ``path`` was added this run as it is now (``c`` took it while it
        landed), or is being added."""
        try:
            size = path.stat().st_size
        except OSError:
            return False
        return self._taken.get(path) == size or any(j.path == path for j in self._queued)

    def on_ingest_file(self, message: IngestFile) -> None:
        if any(job.path == message.path for job in self._queued):
            self.notify(f"{visible(message.path.name, lines=False)} is being added already",
                        markup=False)
            return
        self.enqueue(FrameJob(message.position, message.path, message.retake))

    def on_check_position(self, message: CheckPosition) -> None:
        if FrameJob(message.position) not in self._queued:
            self.enqueue(FrameJob(message.position))

    def enqueue(self, job: FrameJob) -> None:
        """Queue ``job`` for the frame worker; a file's arrival is said at once."""
        if job.path is not None:
            self._tell(FrameArrived(job.position, job.path.name, len(self._queued)))
        self._queued.append(job)
        self._frames.put(job)

    @work(thread=True, group="frames")
    def frame_worker(self) -> None:
        """The frame work, one job at a time in arrival order, until the app ends."""
        while not self.stop.is_set():
            try:
                job = self._frames.get(timeout=0.25)
            except queue.Empty:
                continue
            try:
                session = load_session(self._session_path())
                if job.path is None:
                    self.check_position(session, job.position)
                else:
                    self._settled(job.path)
                    self.ingest(session, job.path, job.position, job.retake)
            except RigkitError as exc:
                self.tell(FrameRefused(job.position, str(exc)))
            finally:
                self.call_from_thread_safe(self._queued.remove, job)

    def _session_path(self) -> Path:
        assert self.session is not None
        return self.session.path

    def call_from_thread_safe(self, call: object, *args: object) -> None:
        """``call(*args)`` on the app's thread, unless the app has ended."""
        with contextlib.suppress(RuntimeError):
            self.call_from_thread(call, *args)  # type: ignore[arg-type]

    def _settled(self, path: Path) -> None:
        """Wait until ``path`` stops growing (``c`` on a frame still being written)."""
        size = -1
        while not self.stop.is_set():
            try:
                now = path.stat().st_size
            except OSError:
                return  # adding it says why
            if now == size and now > 0:
                return
            size = now
            time.sleep(self.config.settle_s)

    def ingest(self, session: Session, path: Path, position: str, retake: bool = False
               ) -> None:
        """Copy ``path`` into the session for ``position``, then run its on-site checks
        (blocking; called from the frame worker): staged, hashed and decoded once
        (:func:`rigkit.capture.field.ingest`; what is refused at a glance is told before
        it is read whole). A frame that does not match the position's burst is held back
        with a question instead (unless ``retake``)."""
        from rigkit.capture.field import frames_at, ingest, newest_failed

        retake = retake or newest_failed(session, position)  # a retake joins no burst
        try:
            done = ingest(session, position, path, replace_existing=retake,
                          burst=not retake, check_burst=not retake)
        except RigkitError as exc:
            self.tell(FrameRefused(position, str(exc)))
            return
        except OSError as exc:  # a full card or disk, a read-only session
            self.tell(FrameRefused(position, environment_message(exc)))
            return
        if done.held is not None:
            self.tell(FrameHeld(position, path, done.held, done.held.elsewhere))
            return
        session = done.session
        with contextlib.suppress(OSError):
            self._taken[path] = path.stat().st_size
        self.post_message(SessionChanged(session))
        self.tell(FrameAdded(position, path.name, len(frames_at(session, position))))
        self.check_position(session, position)

    def check_position(self, session: Session, position: str) -> None:
        """Run the on-site checks of ``position``'s newest frame and show them (blocking).
        Those of a frame already checked are shown again as they were."""
        from rigkit.capture.field import frames_at, onsite_checks
        from rigkit.capture.views import check_image

        frames = frames_at(session, position)
        if not frames:
            return
        known = self.outcome(session, position)
        if known is not None:
            self.tell(known)
            return
        try:
            checks = onsite_checks(session, position)
            image, _ = check_image(session, frames[-1])
        except RigkitError as exc:
            self.tell(FrameRefused(position, str(exc)))
            return
        checked = FrameChecked(position, Path(frames[-1].file).name, len(frames), checks, image)
        self.outcomes[position] = (_checked_key(session), checked)
        self.tell(checked)

    def outcome(self, session: Session, position: str) -> FrameChecked | None:
        """The checks shown last for ``position``, where they are still those of the
        session's frames as they are now (a later position's checks depend on the left
        frame's)."""
        key, checked = self.outcomes.get(position, (None, None))
        return checked if key == _checked_key(session) else None

    def tell(self, message: Tidings) -> None:
        """From a worker: ``message`` for the screen on show (through the app's thread,
        which keeps each position's latest checks)."""
        self.post_message(Forward(message))

    def on_forward(self, message: Forward) -> None:
        tidings = message.tidings
        if isinstance(tidings, FrameHeld) and self.current_position() != tidings.position:
            self.notify(f"{visible(tidings.path.name, lines=False)} does not fit the "
                        f"{tidings.position} burst; it stays on the card (c adds it at a "
                        "position)", severity="warning", markup=False)
        self._tell(tidings)

    def _tell(self, tidings: Tidings) -> None:
        """``tidings`` to the screen on show (which drops them if it is being replaced)."""
        if self.screen_stack:  # none while the app ends
            self.screen.post_message(tidings)


def _checked_key(session: Session) -> tuple[tuple[str, ...], ...]:
    """What a position's checks depend on: every position's frames."""
    return tuple(tuple(f.sha256 for f in session.bursts.get(p, ())) for p in POSITIONS)
