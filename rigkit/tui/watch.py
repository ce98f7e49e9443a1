"""Frames arriving in a watched folder (a card's mount, a tethering tool's download folder).

A file counts once its size has stopped changing for ``settle_s`` seconds (a camera or a
copy writes it in pieces); files already there when watching starts, hidden files and
files that are not images are ignored. The files are only read, never moved: ingesting
copies them into the session (:func:`rigkit.capture.field.add_position_frame`).
"""

from __future__ import annotations

import os
import stat
import threading
import time
from collections.abc import Iterator
from datetime import datetime
from pathlib import Path

from watchfiles import watch

from rigkit.capture import POSITIONS, Session
from rigkit.capture.model import RAW_DIR
from rigkit.imagefile.rawio import RAW_SUFFIXES
from rigkit.tui.config import SETTLE_S

IMAGE_SUFFIXES = frozenset({".png", ".tif", ".tiff", ".jpg", ".jpeg"}) | RAW_SUFFIXES
CLOCK_ALLOWANCE_S = 3600.0
"""How far a camera's clock (which dates the files on its card) may be behind the
computer's and its frames still count as taken since a session began, seconds."""


def is_frame_file(path: Path) -> bool:
    """An image rigkit can ingest, not hidden (temporary files of copies are)."""
    return path.suffix.lower() in IMAGE_SUFFIXES and not path.name.startswith(".")


def arrivals(folder: Path, stop: threading.Event, settle_s: float = SETTLE_S,
             poll: bool = False) -> Iterator[Path]:
    """Yield each new frame file in ``folder`` (recursively) once it is complete, until
    ``stop`` is set or the folder is gone (a card unmounted). ``poll`` uses polling
    instead of OS notifications (network mounts)."""
    seen = {p for p in folder.rglob("*") if p.is_file()}
    pending: dict[Path, tuple[int, float]] = {}  # path -> (size, when it was last seen)
    step_ms = max(50, int(settle_s * 500))
    for changes in watch(folder, stop_event=stop, debounce=step_ms, step=50,
                         rust_timeout=step_ms, yield_on_timeout=True, force_polling=poll,
                         poll_delay_ms=step_ms, raise_interrupt=False):
        for path in sorted((Path(name) for _, name in changes), key=_written):  # in order
            if path not in seen and is_frame_file(path):
                pending.setdefault(path, (-1, time.monotonic()))
        yield from _settled(pending, seen, settle_s)
        if not folder.is_dir():
            return


def _written(path: Path) -> tuple[float, str]:
    """When ``path`` was last written, and its name: files reported together are taken
    in the order the camera wrote them."""
    try:
        return path.stat().st_mtime, path.name
    except OSError:
        return float("inf"), path.name


def _settled(pending: dict[Path, tuple[int, float]], seen: set[Path], settle_s: float
             ) -> Iterator[Path]:
    now = time.monotonic()
    for path, (size, since) in list(pending.items()):
        try:
            current = path.stat().st_size
        except OSError:  # gone again (a temporary file renamed away)
            del pending[path]
            continue
        if current != size or current == 0:
            pending[path] = (current, now)
        elif now - since >= settle_s:
            del pending[path]
            seen.add(path)
            yield path


def unfiled(folder: Path, session: Session) -> list[Path]:
    """The frame files in ``folder`` (recursively) taken since ``session`` began that it
    does not hold, oldest first: frames that reached the card while ``rigkit field`` was
    closed, or that the operator left on it. A file counts as held where ``raw/`` has one
    of its name (or with a position's prefix, as ingest stores a second one) and size;
    one taken out of a position stays in ``raw/`` and is not offered again."""
    try:
        began = datetime.fromisoformat(session.created_utc).timestamp() - CLOCK_ALLOWANCE_S
    except ValueError:  # session.yaml is the user's to edit: a date it cannot read
        began = float("-inf")
    raw = session.path / RAW_DIR
    found = []
    for path in folder.rglob("*"):
        try:
            info = path.stat()
        except OSError:
            continue
        if not (path.is_file() and is_frame_file(path)) or info.st_mtime < began:
            continue
        held = (raw / name for name in (path.name, *(f"{p}-{path.name}" for p in POSITIONS)))
        if not any(_same_size(copy, info.st_size) for copy in held):
            found.append((info.st_mtime, path))
    return [path for _, path in sorted(found)]


def _same_size(path: Path, size: int) -> bool:
    """Whether ``path`` is a regular file (not a link: the session folder is untrusted)
    of ``size`` bytes."""
    try:
        info = os.lstat(path)
    except OSError:
        return False
    return stat.S_ISREG(info.st_mode) and info.st_size == size
