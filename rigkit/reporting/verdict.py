"""The field verdict on one processed session: do the laser targets agree with the depth?

The goal is an agreement within ``goal_pct`` (1 % of the range). Each target says where
it stands in the same words everywhere (``rigkit process``, ``rigkit report``, ``session
show``, the field TUI): "within 1 %", or by how much it is outside and whether that is
still inside the rig's own 2-sigma at that range (the error budget of
:mod:`rigkit.rig.budget`, evaluated at the *estimate*, so a wild laser reading cannot
widen its own tolerance): "1.43 %: outside 1 %, inside the 2σ of ±1.6 %". The session is
done only when every target is within the goal and nothing the run found (the offset's
share of depth, a burst too short for the air) says the capture misses it.

A target that calibrated the rig's scale (``rigkit rig calibrate``; the profile's
provenance names it) is shown as such and never counted: it cannot prove the scale it
made. The verdict counts the independent targets only, and says where the scale came
from (:func:`rigkit.reporting.scale.scale_source`).
"""

from __future__ import annotations

import math
from collections.abc import Collection, Sequence
from dataclasses import dataclass

from rigkit.capture.comparisons import STATUS_NO_ESTIMATE, STATUS_NO_READING, Comparison
from rigkit.capture.model import Session
from rigkit.capture.results import RunRecord
from rigkit.reporting.scale import (
    RunReference,
    calibration_targets,
    run_scale_note,
    scale_source,
)
from rigkit.rig.budget import ErrorModel, budget_row
from rigkit.rig.profile import RigProfile

GOAL_PCT = 1.0
"""The agreement wanted between the depth estimate and the laser, % of the range."""
BUDGET_SIGMAS = 2.0
"""How many of the rig's expected one-sigma errors a target's 2σ note spans."""
CALIBRATED_LABEL = "calibrated the rig: not a check"
"""What a target that calibrated the rig's scale says beside its own words."""


@dataclass(frozen=True)
class TargetVerdict:
    """One target: ``ok`` (within the goal), the goal and the rig's 2σ at the estimate
    (% of the range), and ``label``, the words every front end shows for it;
    ``calibrated``: it calibrated the rig's scale, so it is not counted."""

    target: str
    ok: bool
    goal_pct: float
    two_sigma_pct: float
    label: str
    calibrated: bool = False


@dataclass(frozen=True)
class Verdict:
    """The session's verdict: ``ok`` when every target is within the goal and no
    shortfall is reported; ``headline`` is one line ("6/6 targets within 1 %: done"),
    ``advice`` what to capture again (may be empty); ``scale`` what the targets say of
    the rig's scale (:func:`rigkit.reporting.scale.run_scale_note`; "" where unknown);
    ``source`` where the scale came from (:func:`rigkit.reporting.scale.scale_source`);
    ``shortfalls`` what the run said makes it miss the goal."""

    ok: bool
    headline: str
    targets: tuple[TargetVerdict, ...]
    advice: tuple[str, ...]
    scale: str = ""
    source: str = ""
    shortfalls: tuple[str, ...] = ()


def row_label(row: Comparison, goal_pct: float = GOAL_PCT) -> str:
    """What a comparison says on its own: "within 1 %", "1.43 %: outside 1 %", "no
    estimate" or "no reading" (the words of :func:`judge_target`, without the rig)."""
    if row.status == STATUS_NO_READING:
        return "no reading"
    if row.status == STATUS_NO_ESTIMATE or not math.isfinite(row.error_pct):
        return "no estimate"
    if abs(row.error_pct) <= goal_pct:
        return f"within {goal_pct:g} %"
    return f"{abs(row.error_pct):.2f} %: outside {goal_pct:g} %"


def two_sigma_pct(profile: RigProfile, range_m: float, frames: int = 1) -> float:
    """The rig's 2σ depth error at ``range_m`` metres, % (NaN where there is no range),
    for ``frames`` per position (the offset's share of the budget shrinks with them)."""
    if not math.isfinite(range_m) or range_m <= 0:
        return math.nan
    model = ErrorModel.from_profile(profile, frames=frames)
    return 100.0 * BUDGET_SIGMAS * budget_row(model, range_m).total_fraction


def judge_target(row: Comparison, profile: RigProfile, goal_pct: float = GOAL_PCT,
                 frames: int = 1, calibrated: bool = False) -> TargetVerdict:
    """One comparison row against the goal, with the rig's 2σ at the estimate;
    ``calibrated``: the row's target calibrated the rig (said, and not a check)."""
    sigma2 = two_sigma_pct(profile, row.estimate_range_m, frames)
    label = row_label(row, goal_pct)
    ok = label.startswith("within")
    if not ok and math.isfinite(row.error_pct) and math.isfinite(sigma2):
        inside = "inside" if abs(row.error_pct) <= sigma2 else "outside"
        label += f", {inside} the 2σ of ±{sigma2:.1f} %"
    if calibrated:
        label += f" ({CALIBRATED_LABEL})"
    return TargetVerdict(row.target, ok, goal_pct, sigma2, label, calibrated)


def judge(rows: Sequence[Comparison], profile: RigProfile, goal_pct: float = GOAL_PCT,
          frames: int = 1, shortfalls: Sequence[str] = (), scale: str = "",
          calibrated: Collection[str] = (), source: str = "") -> Verdict:
    """The verdict on one run's comparison rows (one per target), captured with
    ``frames`` per position; ``shortfalls``: what the run said makes it miss the goal
    (:attr:`rigkit.batch.depthrun.DepthRun.shortfalls`); ``scale``: what the targets
    say of the rig's scale, and ``source`` where it came from, shown with it;
    ``calibrated``: the targets that calibrated the rig, shown and not counted."""
    if not rows:
        return Verdict(False, "no laser targets: nothing to check the depth against", (),
                       ("mark at least one target and fire the laser at it",), scale, source,
                       tuple(shortfalls))
    targets = tuple(judge_target(row, profile, goal_pct, frames, row.target in calibrated)
                    for row in rows)
    counted = [t for t in targets if not t.calibrated]
    passed = sum(t.ok for t in counted)
    done = bool(counted) and passed == len(counted) and not shortfalls
    verdict = "done" if done else "capture again"
    if counted and passed == len(counted) and shortfalls:
        verdict = "capture again: the run says it misses the goal (below)"
    used = len(targets) - len(counted)
    if not counted:
        headline = (f"no independent target: all {used} calibrated the rig and cannot check "
                    "it: mark a target the calibration did not use")
    else:
        more = f" ({used} more calibrated the rig: not counted)" if used else ""
        headline = (f"{passed}/{len(counted)} {'independent ' if used else ''}targets within "
                    f"{goal_pct:g} %{more}: {verdict}")
    return Verdict(done, headline, targets, _advice(rows, targets), scale, source,
                   tuple(shortfalls))


def run_verdict(session: Session, rows: Sequence[Comparison], profile: RigProfile,
                record: RunRecord, goal_pct: float = GOAL_PCT) -> Verdict:
    """The verdict on a session's run (:func:`judge`) from its comparison rows, the rig
    it ran with and its record: the frames it stacked, what it said falls short, what
    its targets say of the scale, the targets that calibrated the rig (shown, not
    counted) and where the scale came from. ``rigkit process`` returns it; the field TUI
    shows the one its run returned, or this on reopening a session (the same function,
    the same words)."""
    calibrated = calibration_targets(profile, session)
    scale = run_scale_note(rows, profile, RunReference.of(record), calibrated)
    return judge(rows, profile, goal_pct, frames=record.burst_length,
                 shortfalls=record.shortfalls, scale=scale, calibrated=calibrated,
                 source=scale_source(profile))


def _advice(rows: Sequence[Comparison], targets: Sequence[TargetVerdict]) -> tuple[str, ...]:
    failed = [(r, t) for r, t in zip(rows, targets, strict=True)
              if not t.ok and not t.calibrated]
    advice = [f"{t.target}: {t.label}" for _, t in failed]
    if any(r.status == STATUS_NO_READING for r, _ in failed):
        advice.append("fire the laser at the targets without a reading")
    if any(r.status == STATUS_NO_ESTIMATE for r, _ in failed):
        advice.append("move those targets onto textured ground seen from the right position")
    off = [r for r, _ in failed if math.isfinite(r.error_pct)]
    if len(off) >= 2 and len({math.copysign(1.0, r.error_pct) for r in off}) == 1:
        advice.append("several targets are off the same way: measure C_lr and C_lb again, "
                      "check the zoom, and take the three frames again")
    elif off:
        advice.append("check where the laser hit those targets and fire at them again")
    return tuple(advice)

