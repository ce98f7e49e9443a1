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
import shutil
from collections.abc import Sequence
from dataclasses import replace
from pathlib import Path
from typing import Any

from rigkit.capture.exif import ExifInfo, read_exif
from rigkit.capture.rawio import image_size
from rigkit.capture.session import (
    DEFAULT_WINDOW_PX,
    DERIVED_DIR,
    POSITIONS,
    RAW_DIR,
    SESSION_FILE,
    Frame,
    LaserReading,
    Session,
    Target,
    check_name,
    is_session,
    log_event,
    save_session,
    utc_now,
)
from rigkit.core.files import temp_file
from rigkit.errors import InputError
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


def _reference(rig_path: Path, session_path: Path) -> str:
    """How session.yaml names the rig file: relative if it is inside the session."""
    try:
        return str(rig_path.resolve().relative_to(session_path.resolve()))
    except ValueError:
        return str(rig_path.resolve())


def file_sha256(path: Path) -> str:
    """Hex SHA-256 of a file's bytes, read in 1 MiB blocks."""
    digest = hashlib.sha256()
    try:
        with path.open("rb") as handle:
            for block in iter(lambda: handle.read(1 << 20), b""):
                digest.update(block)
    except FileNotFoundError:
        raise InputError(f"{path}: no such file") from None
    except OSError as exc:
        raise InputError(f"{path}: cannot read ({exc})") from None
    return digest.hexdigest()


def add_frame(
    session: Session,
    position: str,
    source: str | Path,
    *,
    replace_existing: bool = False,
    burst: bool = False,
    origin: str | None = None,
) -> Session:
    """Copy ``source`` into ``raw/`` as a frame for ``position`` and record it.

    The file is copied byte for byte (never moved), hashed, and checked to decode; its
    EXIF is recorded. A position that already has frames gets this one added to its
    burst with ``burst``, or has them replaced by it with ``replace_existing`` (their
    files stay in ``raw/``); otherwise it is refused. A file already in ``raw/`` (same
    name) is never overwritten: identical content is reused, different content refused.
    ``origin`` is what session.yaml records as the frame's ``source``; by default the
    file's absolute path (a file rigkit made itself says so instead, e.g. ``rendered by
    rigkit synth, seed 7``, which does not depend on the machine).
    """
    if position not in POSITIONS:
        raise InputError(f"position {position!r}: expected one of {', '.join(POSITIONS)}")
    source = Path(source)
    if not source.is_file():
        raise InputError(f"{source}: no such file")
    before = () if replace_existing else session.bursts.get(position, ())
    if before and not burst:
        raise InputError(
            f"{session.path}: already has a {position} frame "
            f"({session.frames[position].file}); use --burst to add to it or --replace "
            "to swap it"
        )
    sha256 = file_sha256(source)
    for taken in before:
        if taken.sha256 == sha256:
            raise InputError(
                f"{source}: the same image as {position} frame {taken.file}; a burst needs "
                "new exposures"
            )
    # Decode before copying: a file that does not decode never enters raw/. The decoded
    # image is cached by content hash, so processing will not decode it again.
    size = image_size(source, session.path / DERIVED_DIR, sha256)
    exif = read_exif(source)
    stored = _ingest(session.path / RAW_DIR, source, position, sha256)
    frame = Frame(
        position=position,
        file=f"{RAW_DIR}/{stored.name}",
        sha256=sha256,
        size_px=size,
        added_utc=utc_now(),
        source=origin or str(source.resolve()),
        exif=exif_fields(exif),
    )
    _check_same_size(session, frame, before)
    updated = replace(session, bursts={**session.bursts, position: (*before, frame)})
    save_session(updated)
    log_event(
        session.path, "add-frame",
        f"{position} {frame.file} sha256={frame.sha256} from {frame.source}",
    )
    return updated


def _check_same_size(session: Session, frame: Frame, burst: tuple[Frame, ...]) -> None:
    """All frames must match: those of the other positions and the position's burst."""
    others = [f for pos, f in session.frames.items() if pos != frame.position]
    for other in (*others, *burst):
        if other.size_px != frame.size_px:
            raise InputError(
                f"{frame.source}: {frame.size_px[0]}x{frame.size_px[1]} px, but the "
                f"{other.position} frame ({other.file}) is "
                f"{other.size_px[0]}x{other.size_px[1]} px; all three must match"
            )


def _ingest(raw_dir: Path, source: Path, position: str, wanted: str) -> Path:
    """Copy ``source`` (SHA-256 ``wanted``) into ``raw_dir`` without overwriting anything.

    Keeps the original file name; if a different file already has it, prefixes the
    position. Returns the stored path.
    """
    raw_dir.mkdir(parents=True, exist_ok=True)
    for name in (source.name, f"{position}-{source.name}"):
        target = raw_dir / name
        if target.exists():
            if file_sha256(target) == wanted:
                return target
            continue
        fd, tmp = temp_file(raw_dir, "ingest")
        try:
            with os.fdopen(fd, "wb") as out, source.open("rb") as original:
                shutil.copyfileobj(original, out, 1 << 20)
                out.flush()
                os.fsync(out.fileno())
            if file_sha256(tmp) != wanted:
                raise InputError(f"{source}: changed while it was being read; try again")
            os.link(tmp, target)  # fails rather than overwrite a file that appeared meanwhile
        finally:
            tmp.unlink(missing_ok=True)
        return target
    raise InputError(
        f"{raw_dir}: already holds different files named {source.name} and "
        f"{position}-{source.name}; rename the file to add"
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
    """Add a target, or add readings to an existing one of the same name.

    The pixel must lie inside the left frame (when it is known) and the window must be an
    odd number of pixels.
    """
    check_name(name, "target name")
    if window_px < 1 or window_px % 2 == 0:
        raise InputError(f"--window {window_px}: expected an odd number of pixels (e.g. 9)")
    for reading in readings:
        if not (math.isfinite(reading.slope_distance_m) and reading.slope_distance_m > 0):
            raise InputError(f"range {reading.slope_distance_m}: expected a positive distance")
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


def check_target_inside(session: Session, target: Target) -> None:
    """InputError if the target's pixel is outside the left frame (when known)."""
    left = session.frames.get("left")
    if left is None:
        return
    width, height = left.size_px
    u, v = target.pixel
    if not (-0.5 <= u <= width - 0.5 and -0.5 <= v <= height - 0.5):
        raise InputError(
            f"{session.path}: target {target.name!r} pixel ({u:g}, {v:g}) is outside the "
            f"{width}x{height} left image"
        )


def frame_problems(session: Session) -> list[str]:
    """Why the session cannot be processed yet: missing or altered frames, targets
    outside the image. Empty when it is ready."""
    problems = []
    for position in POSITIONS:
        burst = session.bursts.get(position, ())
        if not burst:
            problems.append(f"no {position} frame")
        for frame in burst:
            path = session.path / frame.file
            if not path.is_file():
                problems.append(f"{position} frame {frame.file} is missing")
            elif file_sha256(path) != frame.sha256:
                problems.append(
                    f"{position} frame {frame.file} no longer matches the hash recorded at "
                    "ingest (the original was changed)"
                )
    for target in session.targets:
        try:
            check_target_inside(session, target)
        except InputError as exc:
            problems.append(str(exc).split(": ", 1)[1])
    return problems
