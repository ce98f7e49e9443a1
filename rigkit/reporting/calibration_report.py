"""What ``rigkit rig calibrate`` writes and prints once it has fitted the sessions
:mod:`rigkit.reporting.scale` read: the profile's provenance for the fit
(:func:`calibration_record`) and the calibration report (:func:`format_calibration`,
docs/rig-profiles.md, "The calibration report").
"""

from __future__ import annotations

import math
from collections.abc import Sequence

from rigkit.capture.session import utc_now
from rigkit.core.tables import render_table
from rigkit.reporting.scale import CalibrationInput, plain, scale_source
from rigkit.rig.adjustment import (
    MIN_CHECKED,
    PRIOR_CONSTANT,
    PRIOR_SCALE,
    PRIOR_SHAPE,
    LaserTarget,
)
from rigkit.rig.calibration import GLOBAL_P, GOAL_PCT, Check, ScaleFit
from rigkit.rig.profile import RigProfile
from rigkit.rig.provenance import Calibration, CalibrationSource


def calibration_record(fit: ScaleFit, given: CalibrationInput) -> Calibration:
    """The profile's provenance for this fit (what it changed is filled in by
    :func:`rigkit.rig.calibrated.calibrated_profile`)."""
    sources = []
    for run in given.runs:
        mine = [t for t in fit.used if t.run == run.fingerprint]
        sources.append(CalibrationSource(
            name=run.label, path=plain(str(run.session.path.resolve())),
            frames_sha256=run.fingerprint, run_id=plain(run.run_id), taken=run.taken,
            used={_short(t): t.pixel or (math.nan, math.nan) for t in mine},
            held_out=tuple(_short(c.target) for c in fit.held_out
                           if c.target.run == run.fingerprint),
            rejected=tuple(_short(r.target) for r in fit.rejected
                           if r.target.run == run.fingerprint)))
    return Calibration(
        date_utc=utc_now(), from_profile=plain(given.profile.name), sessions=tuple(sources),
        reference_depth_m=fit.reference_m, checks=_checks_line(fit), sigma0=fit.sigma0,
        dof=fit.dof)


def _short(t: LaserTarget) -> str:
    """A target's own name, without its session's."""
    return t.name.rsplit("/", 1)[-1]


def _checks_line(fit: ScaleFit) -> str:
    parts = []
    if fit.checks:
        within = sum(c.within for c in fit.checks)
        parts.append(f"leave-one-out: {within}/{len(fit.checks)} targets within "
                     f"{GOAL_PCT:g} %")
    else:
        parts.append(f"unchecked: {len(fit.used)} target(s), fewer than {MIN_CHECKED}")
    if fit.held_out:
        within = sum(c.within for c in fit.held_out)
        parts.append(f"held out: {within}/{len(fit.held_out)} within {GOAL_PCT:g} %")
    return "; ".join(parts)


def format_calibration(fit: ScaleFit, given: CalibrationInput,
                       changes: Sequence[str] = (), kept: Sequence[str] = ()) -> str:
    """The calibration report (docs/rig-profiles.md, "The calibration report"): the rig,
    the sessions, the a-priori and fitted values, the test of unit weight, each row's
    residual, what was left out and why, the leave-one-out and held-out checks."""
    profile = given.profile
    lines = _rig_lines(profile) + _session_lines(fit, given)
    lines += _value_lines(fit, profile)
    lines += _test_lines(fit)
    lines += _residual_lines(fit)
    lines += _check_lines(fit)
    lines += _laser_lines(fit, profile)
    if changes or kept:
        lines.append("written:")
        lines += [f"  {line}" for line in (*changes, *kept)]
    return "\n".join(lines) + "\n"


def _rig_lines(profile: RigProfile) -> list[str]:
    camera = profile.cameras["left"]
    lines = [f"rig       {plain(profile.name)} ({plain(camera.model)}); scale "
             f"{scale_source(profile)}"]
    note = plain(profile.notes.strip().splitlines()[0]) if profile.notes.strip() else ""
    if note:
        lines.append(f"          notes: {note}")
    return lines


def _session_lines(fit: ScaleFit, given: CalibrationInput) -> list[str]:
    lines = []
    for run in given.runs:
        count = sum(t.run == run.fingerprint for t in fit.used)
        lines.append(f"session   {run.label}: run {plain(run.run_id)}, frames taken "
                     f"{run.taken}, {count} target(s) fitted, reference depth "
                     f"{run.reference.median_depth_m:.1f} m")
    for run in given.check_runs:
        lines.append(f"check     {run.label}: run {plain(run.run_id)}, frames taken "
                     f"{run.taken}: its targets only check the fit")
    lines += [f"          {note}" for note in given.notes]
    for kept, copies in fit.duplicates:
        lines.append(f"          {', '.join(c.name for c in copies)}: the same pixel and "
                     f"reading as {kept.name}: counted once")
    spread = [t.laser_m for t in fit.used]
    lines.append(f"fitted    {len(fit.used)} laser target(s), {min(spread):.1f}-"
                 f"{max(spread):.1f} m; the scale pinned at {fit.reference_m:.1f} m")
    return lines


def _value_lines(fit: ScaleFit, profile: RigProfile) -> list[str]:
    """A-priori against fitted values, one sigma each."""
    lb, lr = profile.baseline_lb, profile.baseline_lr
    rows = [["C_lb", f"{lb.value_m:.4f} +- {lb.tolerance_m:.4f} m",
             f"{lb.value_m * fit.scale:.4f} +- {lb.value_m * fit.scale_sigma:.4f} m",
             f"the depth maps' scale to +-{100 * fit.map_scale_sigma:.3f} %"]]
    prior_shape = math.hypot(profile.focal_tolerance, lr.relative_tolerance)
    if fit.shape_fitted:
        rows.append(["f*C_lr", f"x 1 +- {prior_shape:.4f}",
                     f"x {fit.shape:.4f} +- {fit.shape_sigma:.4f}",
                     "shared between f and C_lr by their tolerances"])
    else:
        alone = (f"the targets alone: +-{fit.shape_targets_sigma:.4f}"
                 if math.isfinite(fit.shape_targets_sigma) else "the targets do not see it")
        rows.append(["f*C_lr", f"x 1 +- {prior_shape:.4f}", "held",
                     f"({alone}; no better than the profile's)"])
    table = render_table(["value", "a priori", "fitted", ""], rows, left=(0, 3), indent=2)
    lines = ["values (one sigma):", table.rstrip()]
    for name, w in fit.overruled:
        lines.append(f"  {name}: the profile's value overruled by the lasers "
                     f"(--beyond-tolerance; it was {w:.1f} standardised residuals off)")
    return lines


def _test_lines(fit: ScaleFit) -> list[str]:
    if not fit.dof:
        return ["test      no degrees of freedom: nothing checks the fit"]
    verdict = "passed" if fit.chance >= GLOBAL_P else (
        f"failed at {100 * GLOBAL_P:g} %: the sigmas are scaled by sigma0 = {fit.sigma0:.2f}")
    line = (f"test      sigma0 (a posteriori, of unit weight) {fit.sigma0:.2f}; chi-square "
            f"{fit.chi2:.2f} on {fit.dof} degrees of freedom, chance {fit.chance:.2f}: "
            f"{verdict}")
    lines = [line]
    if len(fit.runs) > 1:
        lines.append(f"one rig   the sessions' own scales agree (chance "
                     f"{fit.one_rig_chance:.2f}): " + ", ".join(
                         f"{r.run} x {r.scale:.4f} +- {r.sigma:.4f}" for r in fit.runs))
    return lines


_PRIOR_SOURCES = {PRIOR_SCALE: "tape", PRIOR_SHAPE: "lens spec, tape",
                  PRIOR_CONSTANT: "laser, a priori 0"}


def _residual_lines(fit: ScaleFit) -> list[str]:
    rows = []
    for r in fit.residuals:
        if r.target is not None:
            t = r.target
            rows.append([r.name, f"{t.laser_m:.2f}", f"{t.estimate_m:.2f}",
                         f"{r.residual_pct:+.3f} %", f"{r.w:+.2f}",
                         f"{r.redundancy:.2f}", ""])
        else:
            what = _PRIOR_SOURCES[r.name]
            value = (f"{r.residual_pct:+.3f} m" if r.name == PRIOR_CONSTANT
                     else f"{r.residual_pct:+.3f} %")
            rows.append([f"{r.name} ({what})", "", "", value, f"{r.w:+.2f}",
                         f"{r.redundancy:.2f}", "prior"])
    for rejected in fit.rejected:
        t = rejected.target
        rows.append([t.name, f"{t.laser_m:.2f}", f"{t.estimate_m:.2f}",
                     f"{rejected.miss_pct:+.3f} %", f"{rejected.w:.1f}", "",
                     "REJECTED: a blunder"])
    table = render_table(["row", "laser m", "estimate m", "residual", "w", "r", ""],
                         rows, left=(0, 6), indent=2)
    lines = ["residuals (the fit minus the observation; w standardised, r redundancy; "
             "blunders beyond |w| 3.29):", table.rstrip()]
    for rejected in fit.rejected:
        lines.append(f"  left out {rejected.target.name}: {rejected.miss_pct:+.2f} % from "
                     f"the fit without it, w = {rejected.w:.1f} (a laser on something "
                     "nearer, or a typo?)")
    return lines


def _check_lines(fit: ScaleFit) -> list[str]:
    lines = []
    if fit.checks:
        lines += ["each target checked by the fit without it and its twins (leave-one-out):",
                  _check_table(fit.checks),
                  f"checked: {sum(c.within for c in fit.checks)}/{len(fit.checks)} targets "
                  f"within {GOAL_PCT:g} % of their laser"]
    else:
        lines.append(f"calibrated but unchecked: {len(fit.used)} target(s); {MIN_CHECKED} or "
                     "more check each against a fit without it")
    if fit.held_out:
        lines += ["held out of the fit, checked against it:", _check_table(fit.held_out),
                  f"held out: {sum(c.within for c in fit.held_out)}/{len(fit.held_out)} "
                  f"targets within {GOAL_PCT:g} % of their laser"]
    return lines


def _check_table(checks: Sequence[Check]) -> str:
    rows = [[c.target.name, f"{c.target.laser_m:.2f}", f"{c.target.estimate_m:.2f}",
             f"{c.calibrated_m:.2f}", f"{c.miss_pct:+.2f} +- {c.sigma_pct:.2f}",
             f"within {GOAL_PCT:g} %" if c.within else f"OUTSIDE {GOAL_PCT:g} %"]
            for c in checks]
    return render_table(["target", "laser m", "before m", "calibrated m", "miss %", ""],
                        rows, left=(0, 5), indent=2).rstrip()


def _laser_lines(fit: ScaleFit, profile: RigProfile) -> list[str]:
    spec = profile.rangefinder
    offset = spec.offset_m if spec is not None else None
    where = (f"the profile's rangefinder offset (right {offset[0]:+.3f}, up "
             f"{offset[1]:+.3f}, forward {offset[2]:+.3f} m)" if offset is not None
             else "no rangefinder offset in the profile: its aperture taken at the camera's")
    value, sigma = fit.laser_constant_m
    if fit.laser_constant_seen:
        constant = (f"{value:+.2f} +- {sigma:.2f} m, determined by the targets (a priori 0 "
                    f"+- {fit.laser_constant_prior_m:.2f} m)")
    else:
        constant = (f"assumed 0 +- {fit.laser_constant_prior_m:.2f} m (one reading's sigma): "
                    f"the targets do not determine it (they leave {value:+.2f} +- "
                    f"{sigma:.2f} m)")
    return [f"laser     additive constant {constant}; {where}"]
