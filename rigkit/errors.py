"""Error types. Every error a user can cause is a :class:`RigkitError`.

The CLI turns a ``RigkitError`` into one line on stderr and a non-zero exit;
anything else is a bug and keeps its traceback.
"""

from __future__ import annotations

import errno


class RigkitError(Exception):
    """A problem with the user's input or environment, explained in one line."""


class InputError(RigkitError):
    """A bad file, value or argument (names the file, key or value)."""


class PipelineError(RigkitError):
    """The depth pipeline cannot produce a trustworthy result from these images."""


_HINTS = {
    errno.ENOSPC: "the disk is full: free some space and run it again",
    errno.EDQUOT: "the disk quota is used up: free some space and run it again",
    errno.EROFS: "the file system is read-only: copy the session to a writable disk",
    errno.EACCES: "permission denied: check who owns it, or copy it somewhere writable",
    errno.EPERM: "not permitted: check who owns it, or copy it somewhere writable",
}


def environment_message(exc: OSError) -> str:
    """One line for an error of the machine rather than of rigkit or the input (a full
    disk, a read-only or unwritable folder): the file, what went wrong, what to do."""
    where = f"{exc.filename}: " if exc.filename else ""
    what = exc.strerror or type(exc).__name__
    hint = _HINTS.get(exc.errno or 0)
    return f"{where}{what}" + (f" ({hint})" if hint else "")
