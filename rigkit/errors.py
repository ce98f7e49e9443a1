"""Error types. Every error a user can cause is a :class:`RigkitError`.

The CLI turns a ``RigkitError`` into one line on stderr and a non-zero exit;
anything else is a bug and keeps its traceback.
"""

from __future__ import annotations


class RigkitError(Exception):
    """A problem with the user's input or environment, explained in one line."""


class InputError(RigkitError):
    """A bad file, value or argument (names the file, key or value)."""


class PipelineError(RigkitError):
    """The depth pipeline cannot produce a trustworthy result from these images."""
