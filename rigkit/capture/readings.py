"""The laser readings of a capture at the tripod: a typed range that looks like a typo,
the range the back view implies to hold it against, and a device's reading as the
session records it."""

from __future__ import annotations

import math
import re
import statistics
from collections.abc import Sequence
from datetime import UTC, datetime

from rigkit.capture.field import frames_at, view_of
from rigkit.capture.model import (
    HISTORY_FILE,
    LaserReading,
    Session,
    Target,
    stray_readings,
)
from rigkit.core.safefs import read_regular
from rigkit.errors import RigkitError
from rigkit.pipeline.checks import implied_range_m
from rigkit.rangefinder.framing import Reading, escape_bytes

TYPO_FACTOR = 1.5
"""A target's first typed range more than this factor from the back view's implied
range or the profile's planned one is doubted (a 3011 typed for 301.1)."""


def reading_doubt(range_m: float, others: Sequence[float], implied_m: float | None,
                  planned_m: float | None) -> str | None:
    """Why a range typed for a target looks like a typo, or None: where the target has
    other readings (m), one that would be a stray among them by the rule processing
    warns of (:func:`rigkit.capture.session.stray_readings`: with one other, both would
    be); else far from the range the back view implied or the profile's planned range
    (m, None where unknown)."""
    if others:
        shots = tuple(LaserReading(r, "", "") for r in (*others, range_m))
        if len(others) in stray_readings(Target("typed", (0.0, 0.0), 1, shots)):
            middle = statistics.median(others)
            return f"{range_m:g} m is far from this target's other readings ({middle:.2f} m)"
        return None
    for what, reference in (("the back view implied", implied_m),
                            ("the profile plans", planned_m)):
        if reference and not reference / TYPO_FACTOR <= range_m <= reference * TYPO_FACTOR:
            return f"{range_m:g} m is far from the ~{reference:.0f} m {what}"
    return None


def implied_range(session: Session) -> float | None:
    """The range (m) the back frame's magnification implies against the left frame,
    None without both or where they cannot be matched."""
    if not (frames_at(session, "left") and frames_at(session, "back")):
        return None
    try:
        view = view_of(session, "back")
    except RigkitError:
        return None
    z = implied_range_m(view.scale, session.rig().baseline_lb.value_m)
    return z if math.isfinite(z) else None


def reading_from_device(reading: Reading, source: str) -> LaserReading:
    """A rangefinder's reading as the session records it; ``source`` is
    ``<protocol>:<port>``."""
    return LaserReading(
        slope_distance_m=reading.slope_distance_m,
        time_utc=datetime.fromtimestamp(reading.timestamp, UTC).strftime("%Y-%m-%dT%H:%M:%SZ"),
        source=source,
        inclination_deg=reading.inclination_deg,
        raw=escape_bytes(reading.raw),
        azimuth_deg=reading.azimuth_deg,
    )


def next_target_name(session: Session) -> str:
    """A name for a new target, ``T<n>`` with n above every target's the session holds
    or ever held (``history.log`` names each target added): a deleted target's name is
    never given again, so the comparisons logged for it stay its own."""
    try:
        history = read_regular(session.path / HISTORY_FILE, HISTORY_LIMIT,
                               "a session's history").decode("utf-8", "replace")
    except (OSError, RigkitError):  # none yet, unreadable or too large: the targets held
        history = ""
    names = [t.name for t in session.targets] + _ADDED.findall(history)
    used = [int(name[1:]) for name in names if re.fullmatch(r"T\d{1,9}", name)]
    return f"T{max(used, default=0) + 1}"


HISTORY_LIMIT = 64 << 20
"""The most of ``history.log`` read for the names of targets once added, bytes."""
_ADDED = re.compile(r"^\S+\s+add-target\s+(\S+) pixel", re.MULTILINE)
"""A target's name in ``history.log``'s line for it (:func:`rigkit.capture.actions.add_target`)."""
