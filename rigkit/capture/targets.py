"""What ``rigkit session`` does to a session's laser targets: add them and their
readings, take them back."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import replace

from rigkit.capture.actions import changing, check_target_inside
from rigkit.capture.model import DEFAULT_WINDOW_PX, LaserReading, Session, Target
from rigkit.capture.session import check_name, log_event, save_session
from rigkit.errors import InputError
from rigkit.rangefinder.ranging import max_range_m


def add_target(
    session: Session,
    name: str,
    pixel: tuple[float, float],
    *,
    window_px: int = DEFAULT_WINDOW_PX,
    readings: Sequence[LaserReading] = (),
    note: str = "",
) -> Session:
    """Add a target, or add readings to an existing one of the same name; returns the
    session as saved.

    The pixel must lie inside the rig's image and the window must be an
    odd number of pixels. The change is made under the session's lock on the session as
    it is on disk then (:func:`changing`), so readings added at once all land.
    """
    check_name(name, "target name")
    if window_px < 1 or window_px % 2 == 0:
        raise InputError(f"--window {window_px}: expected an odd number of pixels (e.g. 9)")
    longest = max_range_m(session.rig())
    for reading in readings:
        if not (math.isfinite(reading.slope_distance_m) and
                0 < reading.slope_distance_m <= longest):
            raise InputError(f"range {reading.slope_distance_m:g} m: expected a distance "
                             f"the rangefinder can measure (0-{longest:g} m)")
    with changing(session.path, "add-target") as current:
        return _add_target(current, name, pixel, window_px, readings, note)


def _add_target(session: Session, name: str, pixel: tuple[float, float], window_px: int,
                readings: Sequence[LaserReading], note: str) -> Session:
    existing = {t.name: t for t in session.targets}
    if name in existing:
        old = existing[name]
        if (tuple(pixel) != old.pixel) or window_px != old.window_px:
            raise InputError(
                f"{session.path}: target {name!r} is already at pixel "
                f"({old.pixel[0]:g}, {old.pixel[1]:g}) window {old.window_px}; "
                "give its pixel and window to add readings, or choose a new name"
            )
        target = replace(old, readings=old.readings + tuple(readings))
        targets = tuple(target if t.name == name else t for t in session.targets)
    else:
        target = Target(name, (float(pixel[0]), float(pixel[1])), window_px, tuple(readings),
                        note)
        check_target_inside(session, target)
        targets = session.targets + (target,)
    updated = replace(session, targets=targets)
    save_session(updated)
    shots = ", ".join(f"{r.slope_distance_m:.2f} m ({r.source})" for r in readings) or "none"
    log_event(
        session.path, "add-target",
        f"{name} pixel ({target.pixel[0]:g}, {target.pixel[1]:g}) window {window_px} "
        f"readings {shots}",
    )
    return updated


def remove_reading(session: Session, target_name: str, number: int) -> Session:
    """Remove reading ``number`` (1-based, as ``session show`` lists them) of the target
    ``target_name``; returns the session as saved."""
    with changing(session.path, "remove") as current:
        target = current.target(target_name)
        if not 1 <= number <= len(target.readings):
            raise InputError(f"{current.path}: target {target_name!r} has "
                             f"{len(target.readings)} reading(s); there is no reading {number}")
        gone = target.readings[number - 1]
        kept = target.readings[: number - 1] + target.readings[number:]
        updated = _with_target(current, replace(target, readings=kept))
        save_session(updated)
        log_event(current.path, "remove", f"{target_name} reading {number}: "
                  f"{gone.slope_distance_m:.2f} m ({gone.source}, {gone.time_utc})")
    return updated


def remove_target(session: Session, target_name: str) -> Session:
    """Remove the target ``target_name`` with its readings; returns the session."""
    with changing(session.path, "remove") as current:
        target = current.target(target_name)
        updated = replace(current, targets=tuple(t for t in current.targets if t is not target))
        save_session(updated)
        log_event(current.path, "remove", f"target {target_name} at ({target.pixel[0]:g}, "
                  f"{target.pixel[1]:g}) with {len(target.readings)} reading(s)")
    return updated


def _with_target(session: Session, target: Target) -> Session:
    return replace(session, targets=tuple(target if t.name == target.name else t
                                          for t in session.targets))
