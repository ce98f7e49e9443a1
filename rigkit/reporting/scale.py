"""What a session's laser targets say of the rig's scale, in the words every front end
shows (``rigkit process``, ``rigkit report``, ``session show``, the field TUI), where the
scale came from (taped, or laser-calibrated: from which sessions and when), and the
sessions and targets that ``rigkit rig calibrate`` fits (:mod:`rigkit.rig.calibration`)
with its report.

A target enters with its laser range (the median of its readings; one sigma: the
device's accuracy and the readings' scatter), its estimated range and the part of that
estimate's sigma which is its own: the disparity offset's share is common to every
target of a run, and is what the fit measures.

A calibration reads each session's current run, the one in its ``results/`` (under the
session's lock, after the repair every command makes: a run stopped between its results
and its log is finished first), never the log's history: the rows of
``results/comparisons.csv`` and the reference of ``results/depth.json``
(:func:`rigkit.capture.session.run_metadata`, read in one place here, ``_depth_json``).
"""

from __future__ import annotations

import hashlib
import io
import math
import os
from collections.abc import Collection, Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np

from rigkit.capture import RESULTS_DIR, Session
from rigkit.capture.comparisons import LOG_NAME, Comparison, latest_run, read_rows
from rigkit.capture.session import POSITIONS, run_metadata, utc_now
from rigkit.core.safefs import read_regular
from rigkit.core.tables import render_table, visible
from rigkit.errors import InputError
from rigkit.rig.calibration import (
    GOAL_PCT,
    MIN_CHECKED,
    PRIOR_CONSTANT,
    PRIOR_SCALE,
    PRIOR_SHAPE,
    Check,
    LaserTarget,
    ScaleFit,
    fit_scale,
)
from rigkit.rig.profile import Calibration, CalibrationSource, RigProfile

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
    that depth (one sigma, a fraction); ``offset_floor`` the least that share can be for
    the run's rig and burst (:func:`offset_floor`; 0: not known)."""

    median_depth_m: float
    offset_fraction: float
    offset_floor: float = 0.0


def _depth_json(folder: Path) -> dict[str, Any] | None:
    """The folder's ``results/depth.json`` (None where none is readable): the one place
    this module reads it (:func:`rigkit.capture.session.run_metadata`)."""
    return run_metadata(folder)


def run_reference(session_path: Path) -> RunReference | None:
    """The latest run's reference (None where the session has no readable run)."""
    results = session_path / RESULTS_DIR
    meta = _depth_json(session_path)
    if meta is None:
        return None
    median = meta.get("median_depth_m")
    if not isinstance(median, int | float):  # a run before depth.json recorded it
        try:
            depth = np.load(io.BytesIO(read_regular(results / "depth.npy")))
        except (OSError, ValueError, InputError):
            return None
        known = depth[np.isfinite(depth)]
        median = float(np.median(known)) if known.size else math.nan
    fraction = meta.get("offset_depth_error_fraction")
    return RunReference(float(median), float(fraction) if isinstance(
        fraction, int | float) else 0.0)


def laser_targets(rows: Sequence[Comparison], reference: RunReference, run: str,
                  accuracy_m: float = LASER_ACCURACY_M, label: str = "") -> list[LaserTarget]:
    """The usable rows of one run (called ``run``; its targets named ``label/T1``, or
    ``T1`` without a label) as targets of the scale fit."""
    targets = []
    for row in rows:
        if not row.ok:
            continue
        e = row.estimate_range_m
        offset_m = e * reference.offset_fraction * e / reference.median_depth_m
        own = math.sqrt(max(row.estimate_sigma_m**2 - offset_m**2, 0.0))
        laser = math.hypot(accuracy_m, row.laser_spread_m / math.sqrt(max(row.laser_readings, 1)))
        name = f"{label}/{row.target}" if label else row.target
        targets.append(LaserTarget(name, row.laser_range_m, laser, e, own,
                                   reference.median_depth_m, run,
                                   max(reference.offset_fraction, reference.offset_floor),
                                   (row.u, row.v), row.window_px))
    return targets


def offset_floor(session: Session, median_depth_m: float) -> float:
    """The least share of depth error (one sigma, a fraction, at ``median_depth_m``) the
    disparity offset leaves for the session's rig and burst: the budget's model without
    heat shimmer (:func:`rigkit.rig.bursts.expected_offset_error_px`). A run can state
    less of its own offset than it has; what C_lb's tolerance counts of it is never less
    than this."""
    from rigkit.rig.bursts import expected_offset_error_px

    profile = session.rig()
    pixels = expected_offset_error_px(profile.image_size, session.burst_length, 0.0)
    return pixels * median_depth_m / (profile.focal_px * profile.baseline_lr.value_m)


# ------------------------------------------------------------ where the scale comes from


def plain(text: str) -> str:
    """``text`` as plain text for any note or file: bytes of a file name that are not
    UTF-8 (kept by Python as lone surrogates) become ``_``, control characters are
    written out (:func:`rigkit.core.tables.visible`)."""
    return visible(os.fsencode(text).decode("utf-8", "replace").replace("\ufffd", "_"))


def frames_fingerprint(session: Session) -> str:
    """One hash of a session's frames (position and SHA-256 of each, in order): the
    capture itself, the same wherever its folder is copied."""
    digest = hashlib.sha256()
    for position in POSITIONS:
        for frame in session.bursts.get(position, ()):
            digest.update(f"{position}:{frame.sha256}\n".encode())
    return digest.hexdigest()


def scale_source(profile: RigProfile) -> str:
    """Where the rig's scale comes from, in one line: taped (the profile as measured), or
    laser-calibrated, when and from which sessions (their targets, when they were taken)."""
    lb = profile.baseline_lb
    value = f"C_lb {lb.value_m:.3f} +- {lb.tolerance_m:.3f} m"
    record = profile.calibration
    if record is None:
        return f"taped ({value}, not laser-calibrated)"
    sessions = ", ".join(f"{plain(s.name)} ({len(s.used)} target{'s' if len(s.used) != 1 else ''}"
                         f", taken {plain(s.taken)})" for s in record.sessions)
    return f"laser-calibrated {record.date_utc[:10]} from {sessions}: {value}"


def calibration_targets(profile: RigProfile, session: Session) -> frozenset[str]:
    """The names of ``session``'s targets that calibrated ``profile`` (same frames, same
    name, same pixel): they cannot also check it."""
    record = profile.calibration
    source = record.source(frames_fingerprint(session)) if record else None
    if source is None:
        return frozenset()
    pixels = {t.name: t.pixel for t in session.targets}
    return frozenset(name for name, pixel in source.used.items()
                     if name in pixels and _same_pixel(pixels[name], pixel))


def _same_pixel(a: tuple[float, float], b: tuple[float, float]) -> bool:
    return abs(a[0] - b[0]) < 0.01 and abs(a[1] - b[1]) < 0.01


# ------------------------------------------------------------------- the scale notes


def calibration_rows(paths: Sequence[Path]) -> frozenset[tuple[str, str]]:
    """(session name, target) of the targets that calibrated each session folder's rig
    (:func:`calibration_targets`; none for a folder that is no readable session)."""
    from rigkit.capture import is_session, load_session

    keys: set[tuple[str, str]] = set()
    for path in paths:
        try:
            session = load_session(path) if is_session(path) else None
        except InputError:
            session = None
        if session is not None:
            keys |= {(session.name, name) for name in calibration_targets(session.rig(),
                                                                          session)}
    return frozenset(keys)


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
    if fit.rejected:
        line += f" (left out: {', '.join(r.target.name for r in fit.rejected)})"
    if not fit.checked:
        line += f" (from {len(fit.used)} target(s): unchecked)"
    return line


def run_scale_note(rows: Sequence[Comparison], profile: RigProfile,
                   reference: RunReference | None, calibrated: Collection[str] = ()) -> str:
    """:func:`scale_note` for one run's rows ("" where no target is usable; the reason
    where the targets disagree). ``calibrated``: the run's targets that calibrated the
    profile, left out: they cannot check the scale they made."""
    if reference is None or not math.isfinite(reference.median_depth_m):
        return ""
    targets = laser_targets([r for r in rows if r.target not in calibrated], reference, "run")
    if not targets:
        if calibrated and any(r.ok for r in rows):
            return (f"calibrated from this session's targets ({', '.join(sorted(calibrated))}):"
                    " they cannot check it; a target the calibration did not use can")
        return ""
    try:
        return scale_note(fit_scale(targets, profile), profile)
    except InputError as exc:
        return f"lasers: {exc}"


def session_scale_note(path: Path) -> str:
    """:func:`run_scale_note` for a session folder's current run ("" where the folder is
    no processed session), with its scale's source after it."""
    from rigkit.capture import is_session, load_session

    if not is_session(path):
        return ""
    try:
        session = load_session(path)
        rows = current_rows(path)
    except InputError:
        return ""
    profile = session.rig()
    note = run_scale_note(rows, profile, run_reference(path),
                          calibration_targets(profile, session)) if rows else ""
    return f"{note}; scale {scale_source(profile)}" if note else f"scale {scale_source(profile)}"


def current_rows(folder: Path, torn: list[str] | None = None) -> list[Comparison]:
    """The comparisons of the run in a session folder's ``results/``: its own copy of
    them (:data:`rigkit.capture.comparisons.LOG_NAME` in ``results/``, there whether or
    not an interrupted run's rows reached the log), else that run's rows in the log (a run
    from before results/ held them), else the log's newest run (no readable results).
    InputError where neither is readable; [] where none."""
    done = folder / RESULTS_DIR / LOG_NAME
    if done.is_file():
        return read_rows(done, torn)
    log = folder / LOG_NAME
    if not log.is_file():
        return []
    rows = read_rows(log, torn)
    run = (_depth_json(folder) or {}).get("run_id")
    mine = [row for row in rows if row.run_id == run]
    return mine if mine else latest_run(rows)


# ------------------------------------------------------------ the sessions calibrated


@dataclass(frozen=True)
class SessionRun:
    """One session as a calibration reads it: the session, its name in the report (plain
    text, unique among those given), its frames' fingerprint, its current run's id, the
    reference and rows of that run."""

    session: Session
    label: str
    fingerprint: str
    run_id: str
    reference: RunReference
    rows: tuple[Comparison, ...]

    @property
    def taken(self) -> str:
        """When its frames were taken (the first frame's EXIF), else when it was made."""
        for position in POSITIONS:
            for frame in self.session.bursts.get(position, ()):
                when = frame.exif.get("datetime_original")
                if when:
                    return plain(str(when))
        return plain(self.session.created_utc)

    def targets(self, accuracy_m: float) -> list[LaserTarget]:
        return laser_targets(self.rows, self.reference, self.fingerprint, accuracy_m,
                             self.label)


@dataclass(frozen=True)
class CalibrationInput:
    """What ``rigkit rig calibrate`` fits: the profile the sessions share, the sessions
    fitted and those given only as checks, the targets to fit and to hold out, and one
    line per session given more than once (taken once)."""

    profile: RigProfile
    runs: tuple[SessionRun, ...]
    check_runs: tuple[SessionRun, ...]
    targets: tuple[LaserTarget, ...]
    held_out: tuple[LaserTarget, ...]
    notes: tuple[str, ...]


def read_sessions(paths: Sequence[Path], check_paths: Sequence[Path] = (),
                  hold_out: Sequence[str] = (), accuracy_m: float = LASER_ACCURACY_M
                  ) -> CalibrationInput:
    """The sessions to calibrate from, each taken once (by its real folder and by its
    frames), each read from its current run under its lock; ``check_paths``: sessions
    whose targets only check the fit; ``hold_out``: target names (``T3``, or
    ``SESSION/T3`` among several sessions) held out as checks. InputError where a session
    is not processed, its results are stale, the rigs differ, a session already
    calibrated its rig, or a name to hold out is no target."""
    notes: list[str] = []
    runs = _unique(paths, (), notes)
    checks = _unique(check_paths, runs, notes)
    if not runs:
        raise InputError("no session given")
    profile = runs[0].session.rig()
    for run in (*runs, *checks):
        _same_rig(run, runs[0], profile)
        record = profile.calibration
        if record is not None and record.source(run.fingerprint) is not None:
            raise InputError(
                f"{run.session.path}: its targets already calibrated its rig "
                f"({plain(profile.name)}, {record.date_utc[:10]}): they cannot calibrate or "
                f"check it again; give it the profile it was calibrated from "
                f"({plain(record.from_profile)}) with rigkit session set-rig, process it, "
                "and calibrate from that")
    targets = [t for run in runs for t in run.targets(accuracy_m)]
    held = _held(targets, hold_out, len(runs))
    held += [t for run in checks for t in run.targets(accuracy_m)]
    kept = [t for t in targets if not any(t is h for h in held)]
    if not kept:
        raise InputError("every target is held out: nothing left to calibrate from")
    return CalibrationInput(profile, tuple(runs), tuple(checks), tuple(kept), tuple(held),
                            tuple(notes))


def _unique(paths: Sequence[Path], before: Sequence[SessionRun], notes: list[str]
            ) -> list[SessionRun]:
    """Each session once: a folder given twice (by any path) or a copy of another's
    frames is taken once, and said."""
    runs: list[SessionRun] = list(before)
    folders = {os.path.realpath(r.session.path): r for r in runs}
    for path in paths:
        real = os.path.realpath(path)
        if real in folders:
            notes.append(f"{plain(str(path))}: the same folder as {folders[real].label}: "
                         "taken once")
            continue
        run = read_run(Path(path))
        if runs:
            _same_rig(run, runs[0], runs[0].session.rig())
        twin = next((r for r in runs if r.fingerprint == run.fingerprint), None)
        if twin is not None:
            notes.append(f"{plain(str(path))}: the same frames as {twin.label} (a copy of "
                         "one capture): taken once")
            continue
        labels = {r.label for r in runs}
        label = run.label if run.label not in labels else f"{run.label}@{len(runs) + 1}"
        run = SessionRun(run.session, label, run.fingerprint, run.run_id, run.reference,
                         run.rows)
        folders[real] = run
        runs.append(run)
    return runs[len(before):]


def read_run(path: Path) -> SessionRun:
    """A session's current run, read under its lock after repairing what an interrupted
    command left (:func:`rigkit.capture.actions.changing`); InputError where it is not
    processed, its results no longer show it, or they hold no laser target."""
    from rigkit.capture.actions import changing, stale_results
    from rigkit.capture.session import load_session

    load_session(path)  # a clear error for a folder that is no session, before locking
    with changing(path, "calibrate") as session:
        stale = stale_results(session)
        if stale:
            raise InputError(f"{session.path}: {stale} (rigkit process {session.path})")
        meta = _depth_json(session.path)
        reference = run_reference(session.path)
        rows = current_rows(session.path)
    run_id = (meta or {}).get("run_id")
    if reference is None or not rows or not isinstance(run_id, str):
        raise InputError(f"{session.path}: not processed with laser targets yet "
                         f"(rigkit process {session.path})")
    if any(row.run_id != run_id for row in rows):
        raise InputError(f"{session.path}: results/{LOG_NAME} is not the run of "
                         f"results/depth.json ({run_id}); process it again")
    reference = replace(reference, offset_floor=offset_floor(session,
                                                            reference.median_depth_m))
    return SessionRun(session, plain(session.name), frames_fingerprint(session), run_id,
                      reference, tuple(rows))


def _same_rig(run: SessionRun, first: SessionRun, profile: RigProfile) -> None:
    if _scale_of(run.session.rig()) != _scale_of(profile):
        raise InputError(
            f"{run.session.path}: its rig differs from {first.session.path}'s (f, C_lr or "
            "C_lb): a rig taped anew is calibrated alone, one session at a time")


def _scale_of(profile: RigProfile) -> tuple[float, float, float]:
    return profile.focal_px, profile.baseline_lr.value_m, profile.baseline_lb.value_m


def _held(targets: Sequence[LaserTarget], names: Sequence[str], runs: int
          ) -> list[LaserTarget]:
    """The targets ``names`` stand for: ``SESSION/T3`` exactly, or ``T3`` in the one
    session that has it."""
    held: list[LaserTarget] = []
    for name in names:
        found = [t for t in targets if t.name == name or (
            "/" not in name and t.name.rsplit("/", 1)[-1] == name)]
        if not found:
            raise InputError(f"--hold-out {plain(name)}: no such target with a depth estimate "
                             "and a reading in the sessions given")
        if len(found) > 1 and runs > 1:
            raise InputError(f"--hold-out {plain(name)}: several sessions have it; name it as "
                             f"{found[0].name}")
        held += found
    return held


# ------------------------------------------------------------------ the report


def calibration_record(fit: ScaleFit, given: CalibrationInput) -> Calibration:
    """The profile's provenance for this fit (what it changed is filled in by
    :func:`rigkit.rig.calibration.calibrated_profile`)."""
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
    verdict = "passed" if fit.chance >= 0.05 else (
        f"failed at 5 %: the sigmas are scaled by sigma0 = {fit.sigma0:.2f}")
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
