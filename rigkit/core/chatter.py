"""Keeping what C libraries print to the terminal away from the user.

LibRaw ("data corrupted at 1378", "Unexpected end of file"), libjpeg ("Premature end of
JPEG file") and libpng ("libpng error: Read Error") write straight to file descriptor
2, below Python's ``sys.stderr``, so neither ``contextlib.redirect_stderr`` nor
logging settings reach them. rigkit's rule is one clear line per problem, so every
call into such a decoder runs inside :func:`captured_stderr`: descriptor 2 points at a
temporary file for the duration, and the caller gets the text to read afterwards (a decoder's
complaint is evidence that a file is cut short) instead of the user seeing it.

Descriptor 2 belongs to the whole process. A capture is by default the only one
running: others wait their turn. A *shared* capture runs alongside other shared ones
(frames decoded in several threads at once, :mod:`rigkit.capture.frames`): they
write into one file, each reads what was printed while it ran, which may then be
another's complaint too, so :func:`attributed` runs a call whose shared capture
complains again alone, where the complaint is its own or absent. A Python thread that
prints to ``sys.stderr`` during a capture lands in it too. The field TUI draws on its
own duplicate of the terminal (:func:`private_terminal`), so a capture in a worker
thread never hides the screen.
"""

from __future__ import annotations

import os
import sys
import tempfile
import threading
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from typing import IO, TextIO, TypeVar

_LIMIT = 64 * 1024
"""At most this much captured text is kept (a decoder can print a line per row)."""

R = TypeVar("R")


class Captured:
    """What a :func:`captured_stderr` block printed: ``text``, set when it ends;
    ``shared``: whether another capture ran meanwhile, whose output ``text`` may hold."""

    text: str = ""
    shared: bool = False


class _Redirect:
    """Descriptor 2's redirection into ``sink`` while any capture is open."""

    def __init__(self) -> None:
        self.sink: IO[bytes] | None = None
        self.saved = -1
        self.open = 0  # captures open
        self.begun = 0  # captures begun, ever
        self.alone = False  # an exclusive capture is open
        self.waiting = 0  # exclusive captures waiting for their turn


_STATE = _Redirect()
_TURN = threading.Condition(threading.Lock())
_THREAD = threading.local()  # .depth: captures this thread has open


@contextmanager
def captured_stderr(shared: bool = False) -> Iterator[Captured]:
    """Redirect file descriptor 2 into a temporary file for the ``with`` block; the
    yielded :class:`Captured` holds the text afterwards (UTF-8 with replacement, at most
    ``_LIMIT`` bytes). Exclusive unless ``shared`` (module docstring); a capture nested
    in another of the same thread joins it without waiting."""
    captured = Captured()
    nested = getattr(_THREAD, "depth", 0) > 0
    state = _STATE
    with _TURN:
        exclusive = not shared and not nested
        if exclusive:
            state.waiting += 1
            _TURN.wait_for(lambda: state.open == 0)
            state.waiting -= 1
            state.alone = True
        elif not nested:  # shared: after the exclusive ones open or waiting
            _TURN.wait_for(lambda: not state.alone and state.waiting == 0)
        if state.open == 0:
            sys.stderr.flush()
            state.sink = tempfile.TemporaryFile()
            state.saved = os.dup(2)
            os.dup2(state.sink.fileno(), 2)
        assert state.sink is not None
        state.open += 1
        state.begun += 1
        begun, crowded = state.begun, state.open > 1
        sink = state.sink
        start = os.lseek(sink.fileno(), 0, os.SEEK_CUR)
    _THREAD.depth = getattr(_THREAD, "depth", 0) + 1
    try:
        yield captured
    finally:
        _THREAD.depth -= 1
        with _TURN:
            sys.stderr.flush()
            end = os.lseek(sink.fileno(), 0, os.SEEK_CUR)
            printed = os.pread(sink.fileno(), min(end - start, _LIMIT), start)
            captured.text = printed.decode("utf-8", errors="replace")
            captured.shared = crowded or state.begun != begun
            state.open -= 1
            if exclusive:
                state.alone = False
            if state.open == 0:
                os.dup2(state.saved, 2)
                os.close(state.saved)
                sink.close()
                state.sink, state.saved = None, -1
            _TURN.notify_all()


def attributed(call: Callable[[], R], complains: Callable[[str], bool]) -> tuple[R, str]:
    """``call()`` in a shared capture, and what it printed. Where that text
    ``complains`` and other captures ran alongside (it may be theirs), ``call()`` runs
    again in an exclusive capture, and that run's result and text are returned: a
    complaint is only ever the call's own."""
    with captured_stderr(shared=True) as chatter:
        result = call()
    if chatter.shared and complains(chatter.text):
        with captured_stderr() as chatter:
            result = call()
    return result, chatter.text


def private_terminal() -> TextIO:
    """A new text stream on a duplicate of descriptor 2 (the terminal), for a
    full-screen program to draw on while descriptor 2 itself is redirected by
    :func:`captured_stderr` from time to time."""
    return os.fdopen(os.dup(2), "w", buffering=1, encoding=sys.stderr.encoding or "utf-8",
                     errors="replace")
