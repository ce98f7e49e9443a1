"""A session folder's lock: every change to a session is made under it (an ``flock`` on
``.lock``, which the operating system releases when its holder dies), and who holds it,
for the messages that say so."""

from __future__ import annotations

import fcntl
import os
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

from rigkit.capture.model import EDIT_WAIT_S, LOCK_FILE
from rigkit.capture.session import utc_now
from rigkit.core.safefs import open_regular
from rigkit.errors import InputError


@contextmanager
def session_lock(path: Path, action: str, wait_s: float = EDIT_WAIT_S) -> Iterator[None]:
    """Hold the session folder ``path``'s lock for ``action`` (e.g. ``process``,
    ``add-frame``): every change to a session is made under it, reading
    ``session.yaml`` afresh inside, so two changes at once never lose one another.
    Waits up to ``wait_s`` seconds for another holder, then InputError naming it ("busy:
    being processed by PID 4242 since ..."). The lock is an ``flock`` on ``.lock``,
    which the operating system releases when its holder dies: a crash leaves nothing to
    clean up."""
    try:  # closed (and so released) below; never a link, a FIFO or a device
        fd = open_regular(path / LOCK_FILE, os.O_RDWR | os.O_APPEND | os.O_CREAT)
    except OSError as exc:
        raise InputError(f"{path / LOCK_FILE}: cannot write to the session's lock "
                         f"({exc.strerror or exc})") from None
    with os.fdopen(fd, "a+") as handle:
        deadline = time.monotonic() + wait_s
        while True:
            try:
                fcntl.flock(handle, fcntl.LOCK_EX | fcntl.LOCK_NB)
                break
            except BlockingIOError:
                if time.monotonic() >= deadline:
                    raise InputError(f"{path}: busy: {_holder(handle)}; try again when it "
                                     "is done") from None
                time.sleep(0.05)
        handle.seek(0)
        handle.truncate()
        handle.write(f"{os.getpid()} {utc_now()} {action}\n")
        handle.flush()
        try:
            yield
        finally:
            handle.truncate(0)  # a holder's name outlives it only if it is killed


def lock_holder(path: Path) -> str | None:
    """Who holds the session folder ``path``'s lock ("being processed by PID 4242 since
    ..."), or None when nobody does. Takes nothing: the lock is tried and let go."""
    try:
        fd = open_regular(path / LOCK_FILE, os.O_RDONLY)
    except OSError:
        return None
    with os.fdopen(fd) as handle:
        try:
            fcntl.flock(handle, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            return _holder(handle)
        fcntl.flock(handle, fcntl.LOCK_UN)
        return None


def _holder(handle: Any) -> str:
    """Who holds the lock, from what its holder wrote into the lock file."""
    handle.seek(0)
    pid, _, rest = handle.read(200).strip().partition(" ")
    since, _, action = rest.partition(" ")
    if not pid.isdigit():
        return "another rigkit command holds it"
    doing = "being processed" if action == "process" else f"{action or 'a change'} running"
    return f"{doing} by PID {pid} since {since}"
