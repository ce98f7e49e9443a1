"""What a session's laser targets say of the rig's scale, in the words every front end
shows (``rigkit process``, ``rigkit report``, the field TUI), and the targets that
``rigkit rig calibrate`` fits (:mod:`rigkit.rig.calibration`).

A target enters with its laser range (the median of its readings; one sigma: the
device's accuracy and the readings' scatter), its estimated range and the part of that
estimate's sigma which is its own: the disparity offset's share is common to every
target of a run, and is what the fit measures.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

from rigkit.capture.comparisons import LOG_NAME, Comparison, latest_run, read_rows
from rigkit.capture.model import Session
from rigkit.capture.results import RunRecord, session_record
from rigkit.core.tables import render_table
from rigkit.errors import InputError
from rigkit.rig.calibration import MIN_CHECKED, LaserTarget, ScaleFit, fit_scale
from rigkit.rig.profile import RigProfile

LASER_ACCURACY_M = 0.3
"""One laser reading's one-sigma error, m, where nothing better is known: a handheld
rangefinder's stated accuracy on a good target (a TruPulse's +-0.3 m)."""


SCALE_NOTICE = 0.001
"""A scale the lasers put further than this (and than 2 sigma) from the profile's is
reported as a finding: 0.1 % of depth."""


@dataclass(frozen=True)
class RunReference:
    """What a run's ``depth.json`` says the scale fit needs: the depth map's median (m,
    the depth the back view pins the scale at) and the offset's share of depth error at
    that depth (one sigma, a fraction)."""

    median_depth_m: float
    offset_fraction: float

    @classmethod
    def of(cls, record: RunRecord) -> RunReference:
        """A run's reference from its record (NaN median without a depth; an unknown
        offset share as 0)."""
        median = record.median_depth_m
        return cls(math.nan if median is None else median, record.offset_depth_fraction or 0.0)


def run_reference(session_path: Path) -> RunReference | None:
    """The latest run's reference: None where the session has none; InputError where
    its record is refused (:func:`rigkit.capture.results.read_record`)."""
    record = session_record(session_path)
    return None if record is None else RunReference.of(record)


def laser_targets(rows: Sequence[Comparison], reference: RunReference, run: str,
                  accuracy_m: float = LASER_ACCURACY_M) -> list[LaserTarget]:
    """The usable rows of one run (called ``run``) as targets of the scale fit."""
    targets = []
    for row in rows:
        if not row.ok:
            continue
        e = row.estimate_range_m
        offset_m = e * reference.offset_fraction * e / reference.median_depth_m
        own = math.sqrt(max(row.estimate_sigma_m**2 - offset_m**2, 0.0))
        laser = math.hypot(accuracy_m, row.laser_spread_m / math.sqrt(max(row.laser_readings, 1)))
        targets.append(LaserTarget(f"{row.session}/{row.target}", row.laser_range_m, laser,
                                   e, own, reference.median_depth_m, run,
                                   reference.offset_fraction))
    return targets


def session_targets(session: Session, accuracy_m: float = LASER_ACCURACY_M
                    ) -> list[LaserTarget]:
    """The targets of a session's latest run; InputError where it has none."""
    reference = run_reference(session.path)
    rows = latest_run(read_rows(session.path / LOG_NAME)) if (
        session.path / LOG_NAME).is_file() else []
    if reference is None or not rows:
        raise InputError(f"{session.path}: not processed with laser targets yet "
                         f"(rigkit process {session.path})")
    return laser_targets(rows, reference, str(session.path.resolve()), accuracy_m)


def scale_note(fit: ScaleFit, profile: RigProfile) -> str:
    """One line: the C_lb the lasers imply against the profile's, and what to do."""
    lb = profile.baseline_lb
    value, sigma = lb.value_m * fit.scale, lb.value_m * fit.scale_sigma
    line = (f"lasers say C_lb = {value:.3f} +- {sigma:.3f} m; the profile says "
            f"{lb.value_m:.3f} +- {lb.tolerance_m:.3f} m")
    if fit.shape_fitted:
        line += f"; and f*C_lr x {fit.shape:.4f} +- {fit.shape_sigma:.4f}"
    off = abs(value - lb.value_m) > 2 * sigma and abs(fit.scale - 1) > SCALE_NOTICE
    line += ": re-tape C_lb, or calibrate (rigkit rig calibrate)" if off else ": consistent"
    if not fit.checked:
        line += f" (from {len(fit.used)} target(s): unchecked)"
    return line


def run_scale_note(rows: Sequence[Comparison], profile: RigProfile,
                   reference: RunReference | None) -> str:
    """:func:`scale_note` for one run's rows ("" where no target is usable; the reason
    where the targets disagree)."""
    if reference is None or not math.isfinite(reference.median_depth_m):
        return ""
    targets = laser_targets(rows, reference, "run")
    if not targets:
        return ""
    try:
        return scale_note(fit_scale(targets, profile), profile)
    except InputError as exc:
        return f"lasers: {exc}"


def format_calibration(fit: ScaleFit, profile: RigProfile, runs: int) -> str:
    """What ``rigkit rig calibrate`` fitted, from what, and each target's check."""
    lb, lr = profile.baseline_lb, profile.baseline_lr
    spread = [t.laser_m for t in fit.used]
    lines = [
        f"fitted from {len(fit.used)} laser target(s) in {runs} session(s), "
        f"{min(spread):.1f}-{max(spread):.1f} m",
        f"C_lb    {lb.value_m:.4f} +- {lb.tolerance_m:.4f} m  ->  {lb.value_m * fit.scale:.4f} "
        f"+- {lb.value_m * fit.scale_sigma:.4f} m  (the depth maps' scale to "
        f"+-{100 * fit.map_scale_sigma:.2f} %)",
    ]
    if fit.shape_fitted:
        lines.append(f"f*C_lr  x {fit.shape:.4f} +- {fit.shape_sigma:.4f} (shared between f "
                     "and C_lr by their tolerances)")
    else:
        lines.append(f"f*C_lr  held (f {profile.focal_px:.0f} px, C_lr {lr.value_m:.3f} m): the "
                     "targets span too little depth to see it")
    for target, miss in fit.strays:
        lines.append(f"left out {target.name}: {miss:+.2f} % from the others' fit, far beyond "
                     "its sigma (a laser on the wrong object, or a typo?)")
    if not fit.checked:
        lines.append(f"calibrated but unchecked: {len(fit.used)} target(s); "
                     f"{MIN_CHECKED} or more check each against a fit without it")
        return "\n".join(lines) + "\n"
    rows = [[c.target.name, f"{c.target.laser_m:.2f}", f"{c.target.estimate_m:.2f}",
             f"{c.calibrated_m:.2f}", f"{c.miss_pct:+.2f} +- {c.sigma_pct:.2f}",
             "within 1 %" if abs(c.miss_pct) <= 1.0 else "OUTSIDE 1 %"] for c in fit.checks]
    table = render_table(["target", "laser m", "before m", "calibrated m", "miss %", ""],
                         rows, left=(0, 5), indent=2)
    within = sum(abs(c.miss_pct) <= 1.0 for c in fit.checks)
    lines += ["each target checked by the fit without it (leave-one-out):", table.rstrip(),
              f"checked: {within}/{len(fit.checks)} targets within 1 % of their laser"]
    return "\n".join(lines) + "\n"


def sessions_targets(paths: Sequence[Path], accuracy_m: float = LASER_ACCURACY_M
                     ) -> tuple[RigProfile, list[LaserTarget]]:
    """The profile the sessions share and the targets of their latest runs. InputError
    where a session is not processed, its results are stale, or the sessions' rigs
    differ (each hand-taped session is calibrated alone)."""
    from rigkit.capture import load_session
    from rigkit.capture.results import stale_results

    profile: RigProfile | None = None
    first = ""
    targets: list[LaserTarget] = []
    for path in paths:
        session = load_session(path)
        stale = stale_results(session)
        if stale:
            raise InputError(f"{session.path}: {stale} (rigkit process {session.path})")
        rig = session.rig()
        if profile is None:
            profile, first = rig, str(session.path)
        elif _scale_of(rig) != _scale_of(profile):
            raise InputError(
                f"{session.path}: its rig differs from {first}'s (f, C_lr or C_lb): a rig "
                "taped anew is calibrated alone, one session at a time")
        targets += session_targets(session, accuracy_m)
    if profile is None:
        raise InputError("no session given")
    return profile, targets


def _scale_of(profile: RigProfile) -> tuple[float, float, float]:
    return profile.focal_px, profile.baseline_lr.value_m, profile.baseline_lb.value_m


def session_scale_note(path: Path) -> str:
    """:func:`run_scale_note` for a session folder's latest run ("" where the folder is
    no processed session)."""
    from rigkit.capture import is_session, load_session

    if not is_session(path) or not (path / LOG_NAME).is_file():
        return ""
    try:
        session = load_session(path)
        rows = latest_run(read_rows(path / LOG_NAME))
    except InputError:
        return ""
    return run_scale_note(rows, session.rig(), run_reference(path))
