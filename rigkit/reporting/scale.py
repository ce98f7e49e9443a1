"""What a session's laser targets say of the rig's scale, in the words every front end
shows (``rigkit process``, ``rigkit report``, ``session show``, the field TUI), where the
scale came from (taped, or laser-calibrated: from which sessions and when), and the
sessions and targets that ``rigkit rig calibrate`` fits (:mod:`rigkit.rig.calibration`;
its report: :mod:`rigkit.reporting.calibration_report`).

A target enters with its laser range (the median of its readings; one sigma: the
device's accuracy and the readings' scatter), its estimated range and the part of that
estimate's sigma which is its own: the disparity offset's share is common to every
target of a run, and is what the fit measures.

A calibration reads each session's current run, the one in its ``results/`` (under the
session's lock, after the repair every command makes: a run stopped between its results
and its log is finished first), never the log's history: the rows of
``results/comparisons.csv`` and the reference of its record, ``results/depth.json``
(:func:`rigkit.capture.results.session_record`).
"""

from __future__ import annotations

import hashlib
import math
import os
from collections.abc import Collection, Sequence
from dataclasses import dataclass, replace
from pathlib import Path

from rigkit.capture.comparisons import LOG_NAME, Comparison, latest_run, read_rows
from rigkit.capture.model import POSITIONS, Session
from rigkit.capture.results import RESULTS_DIR, RunRecord, session_record
from rigkit.core.tables import visible
from rigkit.errors import InputError
from rigkit.rig.adjustment import LaserTarget
from rigkit.rig.calibration import ScaleFit, fit_scale
from rigkit.rig.defaults import LASER_ACCURACY_M
from rigkit.rig.profile import RigProfile

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

    @classmethod
    def of(cls, record: RunRecord) -> RunReference:
        """A run's reference from its record (NaN median without a depth; an unknown
        offset share as 0; no floor)."""
        median = record.median_depth_m
        return cls(math.nan if median is None else median, record.offset_depth_fraction or 0.0)


def run_reference(session_path: Path) -> RunReference | None:
    """The latest run's reference: None where the session has none; InputError where
    its record is refused (:func:`rigkit.capture.results.read_record`)."""
    record = session_record(session_path)
    return None if record is None else RunReference.of(record)


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
    profile = session.rig()  # a refused record of the run: InputError, one line
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
    try:
        record = session_record(folder)
    except InputError:  # a record refused names no run: the log's newest
        record = None
    run = record.run_id if record is not None else None
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
    from rigkit.capture.actions import changing
    from rigkit.capture.results import stale_results
    from rigkit.capture.session import load_session

    load_session(path)  # a clear error for a folder that is no session, before locking
    with changing(path, "calibrate") as session:
        stale = stale_results(session)
        if stale:
            raise InputError(f"{session.path}: {stale} (rigkit process {session.path})")
        record = session_record(session.path)
        rows = current_rows(session.path)
    run_id = record.run_id if record is not None else None
    if record is None or not rows or run_id is None:
        raise InputError(f"{session.path}: not processed with laser targets yet "
                         f"(rigkit process {session.path})")
    if any(row.run_id != run_id for row in rows):
        raise InputError(f"{session.path}: results/{LOG_NAME} is not the run of "
                         f"results/depth.json ({run_id}); process it again")
    reference = RunReference.of(record)
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
