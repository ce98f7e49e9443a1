"""Capture sessions: the frames (RAW or PNG/TIFF/JPEG, with EXIF), laser targets and rig
of one field capture in a folder, the capture check, and the laser comparisons log.

The public names are re-exported here, each imported on first use
(:mod:`rigkit.core.lazy`); modules inside the package import from each other directly.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from rigkit.core.lazy import exports

if TYPE_CHECKING:
    from rigkit.capture.actions import add_frame, create_session, file_sha256, frame_problems
    from rigkit.capture.comparisons import Comparison, latest_run, read_rows
    from rigkit.capture.model import POSITIONS, Frame, LaserReading, Session, Target
    from rigkit.capture.results import RESULTS_DIR
    from rigkit.capture.session import (
        is_session,
        load_session,
        log_event,
        save_session,
        session_to_data,
        utc_now,
    )
    from rigkit.capture.targets import add_target

__all__ = [
    "POSITIONS",
    "RESULTS_DIR",
    "Comparison",
    "Frame",
    "LaserReading",
    "Session",
    "Target",
    "add_frame",
    "add_target",
    "create_session",
    "file_sha256",
    "frame_problems",
    "is_session",
    "latest_run",
    "load_session",
    "log_event",
    "read_rows",
    "save_session",
    "session_to_data",
    "utc_now",
]

__getattr__ = exports(__name__, {
    "Comparison": "comparisons",
    "Frame": "model",
    "LaserReading": "model",
    "POSITIONS": "model",
    "RESULTS_DIR": "results",
    "Session": "model",
    "Target": "model",
    "add_frame": "actions",
    "add_target": "targets",
    "create_session": "actions",
    "file_sha256": "actions",
    "frame_problems": "actions",
    "is_session": "session",
    "latest_run": "comparisons",
    "load_session": "session",
    "log_event": "session",
    "read_rows": "comparisons",
    "save_session": "session",
    "session_to_data": "session",
    "utc_now": "session",
})
