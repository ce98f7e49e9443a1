"""One type for everything rigkit finds about a rig or a capture: a warning of the rig
check, an EXIF finding, an on-site check of a frame as it is taken."""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class Finding:
    """One finding: a stable ``code`` for machines, a one-line ``message`` for people.

    ``ok``: a check that passed (its message says what it measured) rather than a
    problem; ``redo``: for a problem with a frame, what to take again and how.
    ``frame`` (left/right/back) and ``field`` (EXIF tag) are set for capture findings.
    """

    code: str
    message: str
    frame: str | None = None
    field: str | None = None
    ok: bool = False
    redo: str = ""
