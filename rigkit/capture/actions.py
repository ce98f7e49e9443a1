"""What ``rigkit session`` does to a session folder: create it, ingest frames, add
laser targets, and say whether it is ready to process.

Frames are copied into ``raw/`` byte for byte (never moved or overwritten), hashed and
decoded once to prove them readable; every change is saved to ``session.yaml``
atomically and logged in ``history.log``.
"""

from __future__ import annotations

import hashlib
import math
import os
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from dataclasses import replace
from pathlib import Path
from typing import Any

from rigkit.capture.comparisons import LOG_NAME, SIGNIFICANT_DIGITS, append_rows, read_rows
from rigkit.capture.exif import ExifInfo, read_exif
from rigkit.capture.frames import FrameFile, capture_problems
from rigkit.capture.imagesize import check_before_copy
from rigkit.capture.lock import session_lock
from rigkit.capture.rawio import is_raw, load_linear_grey
from rigkit.capture.session import (
    DEFAULT_WINDOW_PX,
    DERIVED_DIR,
    EDIT_WAIT_S,
    POSITIONS,
    RAW_DIR,
    RESULTS_DIR,
    SESSION_FILE,
    STAGING_DIR,
    Frame,
    LaserReading,
    Session,
    Target,
    check_name,
    is_session,
    load_session,
    log_event,
    run_metadata,
    save_session,
    utc_now,
)
from rigkit.core.files import file_sha256, fsync_folder, recover_folder, temp_file
from rigkit.core.safefs import real_folder, require_file
from rigkit.errors import InputError
from rigkit.rangefinder.ranging import max_range_m
from rigkit.rig.profile import load_rig, rig_to_dict


def create_session(
    path: str | Path, rig_path: str | Path, *, operator: str = "", notes: str = ""
) -> Session:
    """Create a new session folder holding a copy of the rig profile's values.

    The folder may exist but must not already be a session. The profile is validated
    first; nothing is written if it is bad.
    """
    path = Path(path)
    rig_path = Path(rig_path)
    check_name(path.name, "session name")
    if is_session(path):
        raise InputError(f"{path}: already a session ({SESSION_FILE} exists)")
    profile = load_rig(rig_path)
    session = Session(
        path=path,
        name=path.name,
        created_utc=utc_now(),
        rig_reference=_reference(rig_path, path),
        rig_sha256=file_sha256(rig_path),
        rig_values=rig_to_dict(profile),
        bursts={},
        operator=operator,
        notes=notes,
    )
    (path / RAW_DIR).mkdir(parents=True, exist_ok=True)
    save_session(session)
    log_event(path, "new", f"rig {rig_path} ({profile.name})")
    return session


def create_session_in(folder: Path, name: str, rig_path: str | Path) -> Session:
    """A new session called ``name`` inside the capture ``folder`` (:func:`create_session`);
    ``name`` is a plain name, never a path: ``../x`` or ``/x`` would put the session
    somewhere else."""
    check_name(name, "session name")
    return create_session(Path(folder) / name, rig_path)


def _reference(rig_path: Path, session_path: Path) -> str:
    """How session.yaml names the rig file: relative if it is inside the session."""
    try:
        return str(rig_path.resolve().relative_to(session_path.resolve()))
    except ValueError:
        return str(rig_path.resolve())


def add_frame(
    session: Session,
    position: str,
    source: str | Path,
    *,
    replace_existing: bool = False,
    burst: bool = False,
    origin: str | None = None,
) -> Session:
    """Copy ``source`` into ``raw/`` as a frame for ``position`` and record it; returns
    the session as saved.

    The file is copied byte for byte (never moved) into a staging folder outside
    ``raw/``, hashed as it is copied, decoded and checked there: it must hold a picture,
    have the rig's image size and that of the frames already taken, not be another
    frame of the session, and be RAW if they are (or not if they are not). Only a frame
    that passes is moved into ``raw/``; a refused one leaves nothing behind. Its EXIF is
    recorded. A position that already has frames gets this one added to its burst with
    ``burst``, or has them replaced by it with ``replace_existing`` (their files stay in
    ``raw/``); otherwise it is refused. A file already in ``raw/`` (same name) is never
    overwritten: identical content is reused, different content gets the position as a
    prefix. ``origin`` is what session.yaml records as the frame's ``source``; by default
    the file's absolute path (a file rigkit made itself says so instead, e.g.
    ``rendered by rigkit synth, seed 7``, which does not depend on the machine).

    The change is made under the session's lock on the session as it is on disk then
    (:func:`rigkit.capture.lock.session_lock`), so concurrent changes all land.
    """
    source = Path(source)
    check_frame_file(session, position, source)
    with changing(session.path, "add-frame") as current:
        with _staged(current.path, source) as (staged, sha256):
            frame = _checked_frame(current, position, source, staged, sha256,
                                   replace_existing, burst, origin)
            stored = _store(current.path / RAW_DIR, staged, _text_name(source.name),
                            position, sha256)
        frame = replace(frame, file=f"{RAW_DIR}/{stored.name}")
        before = () if replace_existing else current.bursts.get(position, ())
        updated = replace(current, bursts={**current.bursts, position: (*before, frame)})
        save_session(updated)
        log_event(current.path, "add-frame",
                  f"{position} {frame.file} sha256={frame.sha256} from {frame.source}")
    return updated


def check_frame_file(session: Session, position: str, source: Path) -> None:
    """InputError naming ``source`` where what is cheap to know refuses it before it is
    read whole: no such position, no such file, or a size on the file or in its header
    that is not a frame of the session's rig (:func:`check_before_copy`)."""
    if position not in POSITIONS:
        raise InputError(f"position {position!r}: expected one of {', '.join(POSITIONS)}")
    require_file(source)
    rig = session.rig()
    check_before_copy(source, rig.image_size, f"the rig profile {rig.name} is for",
                      raw=is_raw(source))


def _text_name(name: str) -> str:
    """``name`` as text that every file and log takes: bytes of a file name that are not
    UTF-8 (which Python keeps as lone surrogates) become ``_``."""
    return os.fsencode(name).decode("utf-8", "replace").replace("\ufffd", "_")


def _checked_frame(session: Session, position: str, source: Path, staged: Path,
                   sha256: str, replace_existing: bool, burst: bool,
                   origin: str | None) -> Frame:
    """The Frame ``staged`` (a copy of ``source``) would be at ``position``, or
    InputError naming ``source`` and what is wrong with it."""
    before = () if replace_existing else session.bursts.get(position, ())
    if before and not burst:
        raise InputError(
            f"{session.path}: already has a {position} frame "
            f"({session.frames[position].file}); use --burst to add to it or --replace "
            "to swap it"
        )
    bursts = session_frames(session)
    kept = bursts.get(position, ())[: len(before)]
    bursts[position] = (*kept, FrameFile(staged, sha256, str(source)))
    problems = capture_problems(bursts, complete=False)
    if problems:
        raise InputError("; ".join(problems))
    rig = session.rig()  # every frame has its size, so all frames agree
    try:
        grey = load_linear_grey(staged, session.path / DERIVED_DIR, sha256, rig.image_size,
                                f"the rig profile {rig.name} is for")
    except InputError as exc:  # name the file the user gave, not the staged copy
        raise InputError(str(exc).replace(str(staged), str(source))) from None
    size = (grey.shape[1], grey.shape[0])
    return Frame(
        position=position,
        file="",  # where it will be stored in raw/
        sha256=sha256,
        size_px=size,
        added_utc=utc_now(),
        source=origin or _text_name(str(source.resolve())),
        exif=exif_fields(read_exif(staged)),
    )
@contextmanager
def changing(path: Path, action: str, wait_s: float = EDIT_WAIT_S) -> Iterator[Session]:
    """The session at ``path`` as it is on disk, for a change made under its lock
    (:func:`rigkit.capture.lock.session_lock`; ``action`` names the change for
    others), after repairing what an interrupted command left (:func:`repair_session`)."""
    with session_lock(path, action, wait_s):
        repair_session(path)
        yield load_session(path)


def repair_session(path: Path) -> None:
    """Undo what a crash or ``kill -9`` left in the session folder ``path`` (under its
    lock): staged copies of frames; a results swap stopped between its renames
    (:func:`rigkit.core.files.recover_folder`); a run whose results were swapped in but
    whose rows never reached the comparisons log (they are appended from
    ``results/comparisons.csv``)."""
    clean_staging(path)
    recover_folder(path, RESULTS_DIR)
    done = path / RESULTS_DIR / LOG_NAME
    if not done.is_file():
        return
    try:
        rows = read_rows(done)
    except InputError:  # derived and damaged: the next run replaces it; it blocks nothing
        return
    log = path / LOG_NAME
    logged = {row.run_id for row in read_rows(log)} if log.is_file() else set()
    missing = [row for row in rows if row.run_id not in logged]
    if missing:
        append_rows(log, missing)
        log_event(path, "repair", f"run {missing[0].run_id}: its {len(missing)} rows appended "
                  "to the comparisons log after an interrupted run")


def stale_results(session: Session, with_targets: bool = True) -> str | None:
    """Why ``results/`` no longer shows this session (frames, rig or, ``with_targets``,
    targets changed since the run that wrote it), or None. Without the targets: whether
    its depth map is still this session's (the depth does not depend on them)."""
    meta_path = session.path / RESULTS_DIR / "depth.json"
    if not meta_path.is_file():
        return None
    meta = run_metadata(session.path)
    if meta is None:  # damaged, a link or a FIFO
        return "results/depth.json is unreadable; process again"
    try:
        recorded = {pos: [f.get("sha256") for f in meta["frames"][pos]] for pos in POSITIONS}
    except (KeyError, TypeError, AttributeError):
        return "results/depth.json is unreadable; process again"
    current = {pos: [f.sha256 for f in session.bursts.get(pos, ())] for pos in POSITIONS}
    run = meta.get("run_id", "?")
    if recorded != current:
        return f"results/ are from run {run}, before the frames changed; process again"
    rig, used = session.rig().geometry(), meta.get("rig") or {}
    now = {"focal_px": rig.focal_px, "baseline_lr_m": rig.baseline_lr_m,
           "baseline_lb_m": rig.baseline_lb_m, "one_camera": rig.one_camera}
    if any(used.get(key, value) != value for key, value in now.items()):
        return f"results/ are from run {run}, before the rig changed; process again"
    if not with_targets:
        return None
    done = session.path / RESULTS_DIR / LOG_NAME
    try:
        rows = read_rows(done) if done.is_file() else []
    except InputError:
        return f"results/{LOG_NAME} is unreadable; process again"
    compared = {(r.target, r.u, r.v, r.laser_readings, _log_range(r.laser_range_m))
                for r in rows}
    targets = {(t.name, t.pixel[0], t.pixel[1], len(t.readings), _log_range(_median_m(t)))
               for t in session.targets}
    if compared != targets:
        return f"results/ are from run {run}, before the targets changed; process again"
    return None


def _median_m(target: Target) -> float:
    """The median of a target's readings, m (NaN without one): its laser range in a run."""
    values = sorted(r.slope_distance_m for r in target.readings)
    if not values:
        return math.nan
    middle = len(values) // 2
    return values[middle] if len(values) % 2 else (values[middle - 1] + values[middle]) / 2


def _log_range(value: float) -> str:
    """A range as the comparisons log keeps it (its significant digits; "nan")."""
    return "nan" if not math.isfinite(value) else f"{value:.{SIGNIFICANT_DIGITS}g}"


def session_frames(session: Session) -> dict[str, tuple[FrameFile, ...]]:
    """The session's frames as the depth run takes them (position -> its burst)."""
    return {pos: tuple(FrameFile(session.path / f.file, f.sha256, f.file) for f in burst)
            for pos, burst in session.bursts.items()}


def clean_staging(session_path: Path) -> None:
    """Remove what an interrupted ``add-frame`` left: staged copies, and the partial
    copies (``raw/.ingest.*.tmp``) that rigkit made inside ``raw/`` before it staged
    outside it. Called under the session's lock, when no copy can be under way."""
    folders = [session_path / STAGING_DIR, session_path / RAW_DIR]
    for folder, pattern in zip(folders, ("*", ".ingest.*.tmp"), strict=True):
        if not os.path.lexists(folder):
            continue
        for leftover in real_folder(folder).glob(pattern):  # never a link to raw/ or away
            if leftover.is_file() and not leftover.is_symlink():
                leftover.unlink(missing_ok=True)


@contextmanager
def _staged(session_path: Path, source: Path) -> Iterator[tuple[Path, str]]:
    """A byte-for-byte copy of ``source`` in the session's staging folder (outside
    ``raw/``), fsynced, and the SHA-256 of exactly the bytes copied; removed afterwards,
    whatever happens (a frame that is kept has been linked into ``raw/`` by then)."""
    folder = session_path / STAGING_DIR
    try:
        fd, tmp = temp_file(real_folder(folder, create=True), "frame")
    except OSError as exc:
        raise InputError(f"{session_path}: cannot write to the session ({exc.strerror})"
                         ) from None
    staged = tmp.with_name(f"{tmp.stem}{source.suffix}")  # the decoder goes by the suffix
    digest = hashlib.sha256()
    try:
        os.rename(tmp, staged)
        with os.fdopen(fd, "wb") as out, source.open("rb") as original:
            for block in iter(lambda: original.read(1 << 20), b""):
                digest.update(block)
                out.write(block)
            out.flush()
            os.fsync(out.fileno())
        yield staged, digest.hexdigest()
    finally:
        tmp.unlink(missing_ok=True)
        staged.unlink(missing_ok=True)


def _store(raw_dir: Path, staged: Path, name: str, position: str, wanted: str) -> Path:
    """Link the accepted ``staged`` file (SHA-256 ``wanted``) into ``raw_dir`` without
    overwriting anything: under its original ``name``, or prefixed with the position
    when a different file already has that name. Returns the stored path."""
    real_folder(raw_dir, create=True)  # a link to a folder elsewhere is refused
    for candidate in (name, f"{position}-{name}"):
        target = raw_dir / candidate
        if target.exists():
            if target.is_file() and not target.is_symlink() and file_sha256(target) == wanted:
                return target
            continue
        os.link(staged, target)  # fails rather than overwrite a file that appeared meanwhile
        fsync_folder(raw_dir)
        return target
    raise InputError(
        f"{raw_dir}: already holds different files named {name} and {position}-{name}; "
        "rename the file to add"
    )


def exif_fields(info: ExifInfo) -> dict[str, Any]:
    """The EXIF fields worth keeping in session.yaml (absent ones left out)."""
    keep = (
        "make", "model", "focal_length_mm", "focal_length_35mm_mm", "exposure_time_s",
        "f_number", "iso", "datetime_original",
    )
    return {name: getattr(info, name) for name in keep if getattr(info, name) is not None}


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


def remove_frame(session: Session, position: str, number: int | None = None) -> Session:
    """Remove frame ``number`` (1-based; default the newest) of ``position``'s burst from
    the session; its file stays in ``raw/``. Returns the session."""
    with changing(session.path, "remove") as current:
        burst = current.bursts.get(position, ())
        number = len(burst) if number is None else number
        if not 1 <= number <= len(burst):
            raise InputError(f"{current.path}: the {position} position has {len(burst)} "
                             f"frame(s); there is no frame {number}")
        gone = burst[number - 1]
        bursts = {**current.bursts, position: burst[: number - 1] + burst[number:]}
        updated = replace(current, bursts={p: b for p, b in bursts.items() if b})
        save_session(updated)
        log_event(current.path, "remove", f"{position} frame {number}: {gone.file} (kept in "
                  f"{RAW_DIR}/)")
    return updated


def _with_target(session: Session, target: Target) -> Session:
    return replace(session, targets=tuple(target if t.name == target.name else t
                                          for t in session.targets))


def check_target_inside(session: Session, target: Target) -> None:
    """InputError if the target's pixel is outside the left frame, or its window larger
    than the frame (the rig's image size)."""
    width, height = session.rig().image_size
    u, v = target.pixel
    if not (-0.5 <= u <= width - 0.5 and -0.5 <= v <= height - 0.5):
        raise InputError(
            f"{session.path}: target {target.name!r} pixel ({u:g}, {v:g}) is outside the "
            f"{width}x{height} left image"
        )
    if target.window_px > min(width, height):
        raise InputError(
            f"{session.path}: target {target.name!r} window {target.window_px} px is larger "
            f"than the {width}x{height} image")


def frame_problems(session: Session) -> list[str]:
    """Why the session cannot be processed yet, by the rules processing applies
    (:func:`rigkit.capture.frames.capture_problems`): a position without a frame, one
    file at two positions, RAW mixed with other images; frames missing, altered since
    ingest, links out of the session or not of the rig's image size; targets outside
    the image or with windows larger than it. Empty when it is ready."""
    problems = capture_problems(session_frames(session))
    size = session.rig().image_size
    inside = session.path.resolve()
    for position in POSITIONS:
        for frame in session.bursts.get(position, ()):
            path = session.path / frame.file
            if not path.resolve().is_relative_to(inside):
                problems.append(f"{position} frame {frame.file} is a link to "
                                f"{path.resolve()}, outside the session")
            elif not path.is_file():
                problems.append(f"{position} frame {frame.file} is missing")
            elif file_sha256(path) != frame.sha256:
                problems.append(
                    f"{position} frame {frame.file} no longer matches the hash recorded at "
                    "ingest (the original was changed)"
                )
            elif frame.size_px != size:
                problems.append(
                    f"{position} frame {frame.file} is {frame.size_px[0]}x{frame.size_px[1]}"
                    f" px, the rig's image size {size[0]}x{size[1]} px"
                )
    for target in session.targets:
        try:
            check_target_inside(session, target)
        except InputError as exc:
            problems.append(str(exc).split(": ", 1)[1])
    return problems
