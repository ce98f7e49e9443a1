"""Keeping what C libraries print to the terminal away from the user.

LibRaw ("data corrupted at 1378", "Unexpected end of file"), libjpeg ("Premature end of
JPEG file") and libpng ("libpng error: Read Error") write straight to file descriptor
2, below Python's ``sys.stderr``, so neither ``contextlib.redirect_stderr`` nor
logging settings reach them. rigkit's rule is one clear line per problem, so every
call into such a decoder runs inside :func:`captured_stderr`: descriptor 2 points at a
temporary file for the duration, and the caller gets the text to read afterwards (a decoder's
complaint is evidence that a file is cut short) instead of the user seeing it.

Descriptor 2 belongs to the whole process, so captures are serialised by a lock; a
Python thread that prints to ``sys.stderr`` during one lands in it too. The field TUI
draws on its own duplicate of the terminal (:func:`private_terminal`), so a capture in
a worker thread never hides the screen.
"""

from __future__ import annotations

import os
import sys
import tempfile
import threading
from collections.abc import Iterator
from contextlib import contextmanager
from typing import TextIO

_LOCK = threading.RLock()
_LIMIT = 64 * 1024
"""At most this much captured text is kept (a decoder can print a line per row)."""


class Captured:
    """What a :func:`captured_stderr` block printed: ``text``, set when it ends."""

    text: str = ""


@contextmanager
def captured_stderr() -> Iterator[Captured]:
    """Redirect file descriptor 2 into a temporary file for the ``with`` block; the
    yielded :class:`Captured` holds the text afterwards (UTF-8 with replacement, at most
    ``_LIMIT`` bytes). A capture nested in another (same thread) shares its file.
    """
    captured = Captured()
    with _LOCK, tempfile.TemporaryFile() as sink:
        sys.stderr.flush()
        saved = os.dup(2)
        try:
            os.dup2(sink.fileno(), 2)
            yield captured
        finally:
            sys.stderr.flush()
            os.dup2(saved, 2)
            os.close(saved)
            sink.seek(0)
            captured.text = sink.read(_LIMIT).decode("utf-8", errors="replace")


def private_terminal() -> TextIO:
    """A new text stream on a duplicate of descriptor 2 (the terminal), for a
    full-screen program to draw on while descriptor 2 itself is redirected by
    :func:`captured_stderr` from time to time."""
    return os.fdopen(os.dup(2), "w", buffering=1, encoding=sys.stderr.encoding or "utf-8",
                     errors="replace")
