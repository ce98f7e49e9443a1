"""Frames arriving in a watched folder (a card's mount, a tethering tool's download folder).

A file counts once its size has stopped changing for ``settle_s`` seconds (a camera or a
copy writes it in pieces); files already there when watching starts, hidden files and
files that are not images are ignored. The files are only read, never moved: ingesting
copies them into the session (:func:`rigkit.capture.field.add_position_frame`).

The folder is walked by rigkit itself, again every half of ``settle_s``: only its real
folders (a link, to a file or to a tree elsewhere, is never followed: it could lead to
an unreadable or a huge tree), each read on its own, so an entry that cannot be read, a
link or a name that is not UTF-8 is said in one line (once) and skipped, and watching
goes on. A card holds a few thousand files at most; walking them takes milliseconds.
"""

from __future__ import annotations

import os
import stat
import threading
import time
from collections.abc import Callable, Iterator
from datetime import datetime
from pathlib import Path

from rigkit.capture import POSITIONS, Session
from rigkit.capture.actions import stored_name
from rigkit.capture.model import RAW_DIR
from rigkit.core.tables import visible
from rigkit.imagefile.rawio import RAW_SUFFIXES
from rigkit.tui.config import SETTLE_S

IMAGE_SUFFIXES = frozenset({".png", ".tif", ".tiff", ".jpg", ".jpeg"}) | RAW_SUFFIXES
CLOCK_ALLOWANCE_S = 3600.0
"""How far a camera's clock (which dates the files on its card) may be behind the
computer's and its frames still count as taken since a session began, seconds."""
MAX_DEPTH = 8
"""How many folders deep the watched folder is walked (a card: DCIM/100NIKON/)."""

Say = Callable[[str], None]
"""Where the watcher says what it skipped, one line each."""


def is_frame_file(path: Path) -> bool:
    """An image rigkit can ingest, not hidden (temporary files of copies are)."""
    return path.suffix.lower() in IMAGE_SUFFIXES and not path.name.startswith(".")


def frame_files(folder: Path, say: Say) -> dict[Path, os.DirEntry[str]]:
    """The frame files under ``folder`` (:func:`is_frame_file`), each with its folder
    entry (``stat(follow_symlinks=False)`` when its size or time is needed: a card's
    thousands of files are not looked at one by one on every walk), walking real
    folders only (module docstring); what is skipped is said."""
    found: dict[Path, os.DirEntry[str]] = {}
    stack = [(folder, 0)]
    while stack:
        current, depth = stack.pop()
        try:
            with os.scandir(current) as listing:
                entries = list(listing)
        except OSError as exc:
            say(f"{visible(str(current), lines=False)}: cannot be read "
                f"({exc.strerror or exc}); skipped")
            continue
        for entry in entries:
            path = Path(entry.path)
            try:
                if entry.is_symlink():
                    say(f"{visible(entry.path, lines=False)}: a link; rigkit follows no link "
                        "out of the watched folder; skipped")
                elif entry.is_dir(follow_symlinks=False):
                    if not entry.name.startswith(".") and depth < MAX_DEPTH:
                        stack.append((path, depth + 1))
                elif entry.is_file(follow_symlinks=False) and is_frame_file(path):
                    if _undecodable(entry.name):
                        say(f"{visible(entry.path, lines=False)}: its name is not UTF-8 "
                            "text; rename it to add it")
                    else:
                        found[path] = entry
            except OSError as exc:
                say(f"{visible(entry.path, lines=False)}: cannot be read "
                    f"({exc.strerror or exc}); skipped")
    return found


def _undecodable(name: str) -> bool:
    """Whether a file name holds bytes that are not UTF-8 (kept by Python as lone
    surrogates)."""
    try:
        name.encode("utf-8")
    except UnicodeEncodeError:
        return True
    return False


def arrivals(folder: Path, stop: threading.Event, settle_s: float = SETTLE_S,
             say: Say = lambda line: None) -> Iterator[Path]:
    """Yield each new frame file in ``folder`` (recursively) once it is complete, until
    ``stop`` is set or the folder is gone (a card unmounted). What cannot be watched is
    said through ``say``, once per line, and skipped."""
    said: set[str] = set()

    def once(line: str) -> None:
        if line not in said:
            said.add(line)
            say(line)

    seen = set(frame_files(folder, once))
    pending: dict[Path, tuple[int, float]] = {}  # path -> (size, since when it has it)
    while not stop.wait(max(0.05, settle_s / 2)):
        if not folder.is_dir():
            return
        now = time.monotonic()
        current = {p: _stat(entry) for p, entry in frame_files(folder, once).items()
                   if p not in seen}
        pending = {p: v for p, v in pending.items() if current.get(p) is not None}
        ready = []
        for path, found in current.items():
            if found is None:  # gone again (a temporary file renamed away)
                continue
            size, written = found
            known = pending.get(path)
            if known is None or known[0] != size or size == 0:
                pending[path] = (size, now)
            elif now - known[1] >= settle_s:
                ready.append((written, path.name, path))
        for _, _, path in sorted(ready):  # files complete together: in the order written
            del pending[path]
            seen.add(path)
            yield path


def _stat(entry: os.DirEntry[str]) -> tuple[int, float] | None:
    """A folder entry's size (bytes) and when it was last written (seconds), without
    following a link; None where it is gone."""
    try:
        stat = entry.stat(follow_symlinks=False)
    except OSError:
        return None
    return stat.st_size, stat.st_mtime


def unfiled(folder: Path, session: Session) -> list[Path]:
    """The frame files in ``folder`` (recursively, :func:`frame_files`; what cannot be
    read is left out) taken since ``session`` began that it does not hold, oldest
    first: frames that reached the card while ``rigkit field`` was closed, or that the
    operator left on it. A file counts as held where ``raw/`` has one of its name (or
    with a position's prefix, as ingest stores a second one) and size; one taken out of
    a position stays in ``raw/`` and is not offered again."""
    try:
        began = datetime.fromisoformat(session.created_utc).timestamp() - CLOCK_ALLOWANCE_S
    except ValueError:  # session.yaml is the user's to edit: a date it cannot read
        began = float("-inf")
    raw = session.path / RAW_DIR
    found = []
    for path, entry in frame_files(folder, lambda line: None).items():
        try:
            info = entry.stat(follow_symlinks=False)
        except OSError:  # gone meanwhile
            continue
        if info.st_mtime < began:
            continue
        name = stored_name(path.name)  # as ingest stores it
        held = (raw / n for n in (name, *(f"{p}-{name}" for p in POSITIONS)))
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
