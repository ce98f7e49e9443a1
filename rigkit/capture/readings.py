"""The laser readings of a capture at the tripod: a typed range that looks like a typo,
the range the back view implies to hold it against, and a device's reading as the
session records it."""

from __future__ import annotations

import math
import statistics
from collections.abc import Sequence
from datetime import UTC, datetime

from rigkit.capture.field import frames_at, view_of
from rigkit.capture.model import LaserReading, Session
from rigkit.errors import RigkitError
from rigkit.pipeline.checks import implied_range_m
from rigkit.rangefinder.framing import Reading, escape_bytes

TYPO_SPREAD = 0.05
"""A typed range this far (5 %) from the target's other readings' median is doubted:
one target's readings agree within the laser's metre."""
TYPO_FACTOR = 1.5
"""A target's first typed range more than this factor from the back view's implied
range or the profile's planned one is doubted (a 3011 typed for 301.1)."""


def reading_doubt(range_m: float, others: Sequence[float], implied_m: float | None,
                  planned_m: float | None) -> str | None:
    """Why a range typed for a target looks like a typo, or None: far from the target's
    other readings (m) where it has some, else from the range the back view implied or
    the profile's planned range (m, None where unknown)."""
    if others:
        middle = statistics.median(others)
        if abs(range_m - middle) > TYPO_SPREAD * middle:
            return f"{range_m:g} m is far from this target's other readings ({middle:.1f} m)"
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
