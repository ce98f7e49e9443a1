"""The field verdict on one processed session: do the laser targets agree with the depth?

A target passes when its estimate is within a tolerance of the laser range: ``limit_pct``
(1 % by default), or twice the rig's expected depth error at that range (the error
budget of :mod:`rigkit.rig.budget`) when that is larger, since a rig cannot do better
than its budget. The verdict says what to capture again when a target fails.
"""

from __future__ import annotations

import json
import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

from rigkit.capture import RESULTS_DIR
from rigkit.capture.comparisons import STATUS_NO_ESTIMATE, STATUS_NO_READING, Comparison
from rigkit.pipeline.estimate import offset_warning
from rigkit.rig.budget import ErrorModel, budget_row
from rigkit.rig.profile import RigProfile

LIMIT_PCT = 1.0
"""Default agreement wanted between the depth estimate and the laser, % of the range."""
BUDGET_SIGMAS = 2.0
"""The tolerance never goes below this many of the rig's expected one-sigma errors."""


@dataclass(frozen=True)
class TargetVerdict:
    """One target: ``ok``, its tolerance in % of the laser range, and a note when not ok."""

    target: str
    ok: bool
    tolerance_pct: float
    note: str = ""


@dataclass(frozen=True)
class Verdict:
    """The session's verdict: ``ok`` when every target passes; ``headline`` is one line
    ("6/6 targets within 1 %: done"), ``advice`` what to capture again (may be empty)."""

    ok: bool
    headline: str
    targets: tuple[TargetVerdict, ...]
    advice: tuple[str, ...]


def tolerance_pct(
    profile: RigProfile, range_m: float, limit_pct: float = LIMIT_PCT, frames: int = 1
) -> float:
    """The tolerance at ``range_m`` metres: ``limit_pct`` or the rig's 2-sigma, in %,
    for ``frames`` per position (the offset's share of the budget shrinks with them)."""
    if not math.isfinite(range_m) or range_m <= 0:
        return limit_pct
    model = ErrorModel.from_profile(profile, frames=frames)
    expected = budget_row(model, range_m).total_fraction
    return max(limit_pct, 100.0 * BUDGET_SIGMAS * expected)


def judge_target(row: Comparison, profile: RigProfile, limit_pct: float = LIMIT_PCT,
                 frames: int = 1) -> TargetVerdict:
    """One comparison row against its tolerance (``frames`` per position)."""
    tolerance = tolerance_pct(profile, row.laser_range_m, limit_pct, frames)
    if row.status == STATUS_NO_READING:
        return TargetVerdict(row.target, False, tolerance, "no laser reading")
    if row.status == STATUS_NO_ESTIMATE:
        return TargetVerdict(row.target, False, tolerance, "no depth estimate at the target")
    if abs(row.error_pct) <= tolerance:
        return TargetVerdict(row.target, True, tolerance)
    return TargetVerdict(row.target, False, tolerance, f"off by {row.error_pct:+.1f} %")


def judge(rows: Sequence[Comparison], profile: RigProfile, limit_pct: float = LIMIT_PCT,
          frames: int = 1) -> Verdict:
    """The verdict on one run's comparison rows (one per target), captured with
    ``frames`` per position."""
    if not rows:
        return Verdict(False, "no laser targets: nothing to check the depth against", (),
                       ("mark at least one target and fire the laser at it",))
    targets = tuple(judge_target(row, profile, limit_pct, frames) for row in rows)
    passed = sum(t.ok for t in targets)
    widest = max(t.tolerance_pct for t in targets)
    within = f"{limit_pct:g} %" if widest <= limit_pct else f"tolerance (up to {widest:.1f} %)"
    verdict = "done" if passed == len(targets) else "capture again"
    headline = f"{passed}/{len(targets)} targets within {within}: {verdict}"
    return Verdict(passed == len(targets), headline, targets, _advice(rows, targets))


def _advice(rows: Sequence[Comparison], targets: Sequence[TargetVerdict]) -> tuple[str, ...]:
    failed = [t for t in targets if not t.ok]
    advice = [f"{t.target}: {t.note}" for t in failed]
    if any("reading" in t.note for t in failed):
        advice.append("fire the laser at the targets without a reading")
    if any("estimate" in t.note for t in failed):
        advice.append("move those targets onto textured ground seen from the right position")
    signs = {math.copysign(1.0, r.error_pct) for r, t in zip(rows, targets, strict=True)
             if not t.ok and r.status == "ok"}
    off = sum(1 for t in failed if t.note.startswith("off"))
    if off >= 2 and len(signs) == 1:
        advice.append("several targets are off the same way: measure C_lr and C_lb again, "
                      "check the zoom, and take the three frames again")
    elif off:
        advice.append("check where the laser hit those targets and fire at them again")
    return tuple(advice)


def offset_note(session_path: Path) -> str | None:
    """The warning the session's latest run gave where its disparity offset alone
    leaves more than 0.3 % of depth uncertain (:func:`~rigkit.pipeline.estimate.offset_warning`);
    None without one, or without a readable run."""
    try:
        meta = json.loads((session_path / RESULTS_DIR / "depth.json").read_text("utf-8"))
    except (OSError, ValueError):
        return None
    fraction = meta.get("offset_depth_error_fraction") if isinstance(meta, dict) else None
    return offset_warning(fraction) if isinstance(fraction, int | float) else None
