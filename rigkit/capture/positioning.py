"""Recording what a session knows of its rig beyond frames and targets, under the
session's lock like every other change to a session: where the tripod stood
(``rigkit session set-position``), the rig profile its frames are processed with
(``rigkit session set-rig``, e.g. one ``rigkit rig calibrate`` wrote), and the step the
capture at the tripod was on (``rigkit field`` resumes there)."""

from __future__ import annotations

import os
from dataclasses import replace
from pathlib import Path

from rigkit.capture.lock import session_lock
from rigkit.capture.model import FIELD_STEPS, Session
from rigkit.capture.session import load_session, log_event, save_session
from rigkit.capture.tripod import TripodPosition, check_position
from rigkit.core.files import file_sha256
from rigkit.errors import InputError
from rigkit.rig.profile import load_rig, rig_to_dict


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


def set_rig(path: Path, rig_path: Path) -> Session:
    """Process the session with the profile at ``rig_path`` from now on (a copy of its
    values is kept, as ``session new`` keeps one); returns the session as saved. The
    earlier profile stays named in ``history.log``; the results stay until the session
    is processed again. InputError for a bad profile or one for another image size."""
    profile = load_rig(rig_path)
    with session_lock(Path(path), "set-rig"):
        current = load_session(path)
        size = current.rig().image_size
        if profile.image_size != size:
            raise InputError(
                f"{rig_path}: for {profile.image_size[0]}x{profile.image_size[1]} px frames; "
                f"the session's are {size[0]}x{size[1]} px")
        updated = replace(current, rig_reference=os.path.abspath(rig_path),
                          rig_sha256=file_sha256(rig_path), rig_values=rig_to_dict(profile))
        save_session(updated)
        log_event(current.path, "set-rig", f"rig {rig_path} ({profile.name}; was "
                  f"{current.rig_reference}, {current.rig().name})")
    return updated


def set_field_step(path: Path, step: str) -> Session:
    """Record that ``rigkit field`` is on ``step`` (one of :data:`FIELD_STEPS`), where it
    resumes after a quit or a crash (:func:`rigkit.capture.field.resume_step`); returns
    the session as saved. Not logged: the frames and readings taken there are."""
    if step not in FIELD_STEPS:
        raise InputError(f"step {step!r}: expected one of {', '.join(FIELD_STEPS)}")
    with session_lock(Path(path), "field-step"):
        current = load_session(path)
        if current.field_step == step:
            return current
        updated = replace(current, field_step=step)
        save_session(updated)
    return updated
