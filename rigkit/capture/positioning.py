"""Recording where the tripod stood (``rigkit session set-position``), under the
session's lock like every other change to a session."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

from rigkit.capture.session import Session, load_session, log_event, save_session, session_lock
from rigkit.capture.tripod import TripodPosition, check_position


def set_tripod_position(path: Path, position: TripodPosition) -> Session:
    """Record ``position`` as the session's tripod position (replacing an earlier one,
    which ``history.log`` keeps); returns the session as saved. InputError for a
    position off the Earth's surface or a session that cannot be changed now."""
    check_position(position.lat_deg, position.lon_deg, position.height_m)
    with session_lock(Path(path), "set-position"):
        current = load_session(path)
        updated = replace(current, tripod=position)
        save_session(updated)
        before = current.tripod
        was = "" if before is None else (
            f" (was {before.lat_deg:.7f}, {before.lon_deg:.7f}, {before.height_m:.2f} m)")
        log_event(current.path, "set-position",
                  f"lat {position.lat_deg:.7f} lon {position.lon_deg:.7f} height "
                  f"{position.height_m:.2f} m from {position.source}{was}")
    return updated
