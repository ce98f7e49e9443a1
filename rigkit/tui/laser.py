"""The laser as the field TUI holds it: one link for as long as ``rigkit field`` runs,
whatever screen shows, and every shot kept.

A shot (fired, or typed with ``m``) goes to the selected target; while no target is
selected, or while the session cannot be changed (processing holds its lock), it is
held here and every screen says so, until it can be filed. The app files the held
shots one at a time, oldest first, in a worker (:meth:`rigkit.tui.app.FieldApp.file_shots`);
this class is the state they share, behind one lock.
"""

from __future__ import annotations

import threading
from dataclasses import dataclass

from rigkit.capture import LaserReading


@dataclass(frozen=True)
class Shot:
    """A reading waiting to be filed, for ``target`` (None: whichever is selected when
    it can be filed; a typed range names its target)."""

    reading: LaserReading
    target: str | None = None


class LaserDesk:
    """The link's latest state, the newest shot, the selected target and the shots not
    yet filed (oldest first). Read and changed from the app's thread and its filing
    worker: every change goes through :attr:`lock`."""

    def __init__(self, link: str, selected: str | None) -> None:
        self.link = link  # the link's latest state, one line
        self.followed = False  # a rangefinder (or the demo's) is followed
        self.connected = False
        self.last = ""  # the newest shot and where it went
        self.selected = selected
        self.filing = False  # a worker files the held shots
        self.lock = threading.Lock()
        self._held: list[Shot] = []

    def take(self, shot: Shot) -> None:
        """Keep ``shot`` until it is filed."""
        reading = shot.reading
        with self.lock:
            self._held.append(shot)
            self.last = (f"{reading.time_utc[11:19]} {reading.slope_distance_m:.2f} m "
                         f"{reading.source.split(':', 1)[0]}")
            if reading.source != "manual":
                self.connected = True
                self.link = f"connected; newest reading at {reading.time_utc[11:19]} UTC"

    def held(self) -> list[Shot]:
        with self.lock:
            return list(self._held)

    def start_filing(self) -> bool:
        """Whether a filing worker is to start now (shots to file, a target for them, and
        no worker already at it)."""
        with self.lock:
            if self.filing or self._next() is None:
                return False
            self.filing = True
            return True

    def next_to_file(self) -> tuple[Shot, str] | None:
        """The oldest held shot and the target it goes to, or None (then the worker
        stops: nothing held, or no target selected)."""
        with self.lock:
            found = self._next()
            if found is None:
                self.filing = False
            return found

    def _next(self) -> tuple[Shot, str] | None:
        if not self._held:
            return None
        shot = self._held[0]
        target = shot.target or self.selected
        return None if target is None else (shot, target)

    def filed(self, shot: Shot, target: str) -> None:
        """``shot`` is in the session, in ``target``."""
        with self.lock:
            self._held.remove(shot)
            if not self._held:  # the newest shot: say where it went
                self.last = f"{self.last.split(' -> ')[0]} -> {target}"

    def worth_saying(self) -> bool:
        """Whether screens other than the targets' show the laser's line: a rangefinder
        is followed, or a shot was taken or is held."""
        with self.lock:
            return self.followed or bool(self.last) or bool(self._held)

    def line(self) -> str:
        """What every screen says of the laser, one line (plain text)."""
        with self.lock:
            held = len(self._held)
            words = [f"laser: {self.link}"]
            if self.last:
                words.append(f"last {self.last}")
            if held and self.selected is None:
                words.append(f"{held} held: mark or select a target (targets step)")
            elif held:
                words.append(f"{held} waiting to be saved to {self.selected}")
            return " · ".join(words)
