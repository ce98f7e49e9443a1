"""What ``rigkit session`` does to a session folder: create it, ingest frames, add
laser targets, and say whether it is ready to process.

Frames are copied into ``raw/`` byte for byte (never moved or overwritten), hashed and
decoded once to prove them readable; every change is saved to ``session.yaml``
atomically and logged in ``history.log``.
"""

from __future__ import annotations

import hashlib
import os
import re
import secrets
from collections.abc import Callable, Iterator
from contextlib import contextmanager, suppress
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np

from rigkit.capture.comparisons import LOG_NAME, append_rows, read_rows
from rigkit.capture.frames import FrameFile, capture_problems
from rigkit.capture.lock import session_lock
from rigkit.capture.model import (
    DERIVED_DIR,
    EDIT_WAIT_S,
    POSITIONS,
    RAW_DIR,
    SESSION_FILE,
    STAGING_DIR,
    Frame,
    Session,
    Target,
)
from rigkit.capture.results import RESULTS_DIR, session_comparisons
from rigkit.capture.session import (
    check_name,
    is_session,
    load_session,
    log_event,
    save_session,
    utc_now,
)
from rigkit.core.files import fd_sha256, file_sha256, recover_folder
from rigkit.core.safefs import (
    fd_path,
    kind_of,
    open_folder,
    open_input,
    open_regular,
    remove_files,
    require_file,
    too_large,
)
from rigkit.core.tables import visible
from rigkit.errors import InputError
from rigkit.imagefile.exif import ExifInfo, read_exif
from rigkit.imagefile.imagesize import MAX_FRAME_BYTES, check_before_copy
from rigkit.imagefile.rawio import is_raw, load_linear_grey
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
    the session as saved (:func:`staged_frame`, then :func:`file_frame`)."""
    with staged_frame(session, position, source, replace_existing=replace_existing,
                      burst=burst) as staged:
        return file_frame(staged, origin)


@dataclass(frozen=True)
class StagedFrame:
    """A frame on its way into a session (:func:`staged_frame`): ``session`` as it is on
    disk under its lock; ``position``; ``source``, the file given; ``path``, its copy in
    the staging folder; ``sha256``, the hash of the bytes copied (hex); ``grey``, the
    copy decoded once, (H, W) float32 in [0, 1] of full scale
    (:func:`rigkit.imagefile.rawio.load_linear_grey`; RAW: linear, kept in ``derived/``),
    for every check of it (handed to the on-site checks, :func:`rigkit.capture.views.
    admit`, which may scale it in place); ``raw``, whether it is camera RAW;
    ``replace_existing`` and ``burst``, how it joins the position's frames; ``copy``, the
    copy as the staging folder's descriptor holds it (``path`` reaches it through that
    descriptor), linked into ``raw/`` from there."""

    session: Session
    position: str
    source: Path
    path: Path
    sha256: str
    grey: np.ndarray
    raw: bool
    replace_existing: bool = False
    burst: bool = False
    copy: _Staged | None = None

    @property
    def size(self) -> tuple[int, int]:
        """(W, H) px."""
        return self.grey.shape[1], self.grey.shape[0]


@contextmanager
def staged_frame(session: Session, position: str, source: str | Path, *,
                 replace_existing: bool = False, burst: bool = False
                 ) -> Iterator[StagedFrame]:
    """``source`` staged for ``position``: copied, hashed and decoded once, and checked,
    under the session's lock (:func:`changing`), for a :func:`file_frame` to record.

    What is cheap to know is checked first (:func:`check_frame_file`). The file is then
    copied byte for byte (never moved) into a staging folder outside ``raw/``, hashed as
    it is copied, and checked there: a position that already has frames takes it only
    as one more of its burst (``burst``), or as the frame that replaces them
    (``replace_existing``; their files stay in ``raw/``); it must not be another frame
    of the session, must be RAW if they are (or not if they are not), and, decoded,
    must hold a picture of the rig's image size. A refused frame leaves nothing behind,
    nor does one not filed before the block ends (the staged copy is removed then,
    whatever happens)."""
    source = Path(source)
    check_frame_file(session, position, source)
    with changing(session.path, "add-frame") as current, \
            _staged(current.path, source) as copy:
        path, sha256 = copy.path, copy.sha256
        _check_joins(current, position, source, path, sha256, replace_existing, burst)
        rig = current.rig()  # every frame has its size, so all frames agree
        try:
            grey = load_linear_grey(path, current.path / DERIVED_DIR, sha256, rig.image_size,
                                    f"the rig profile {rig.name} is for")
        except InputError as exc:  # name the file the user gave, not the staged copy
            raise InputError(str(exc).replace(str(path), str(source))) from None
        yield StagedFrame(current, position, source, path, sha256, grey, is_raw(path),
                          replace_existing, burst, copy)


def file_frame(staged: StagedFrame, origin: str | None = None) -> Session:
    """Record ``staged`` in its session (inside :func:`staged_frame`'s block): linked into
    ``raw/`` (a file already there of the same name is never overwritten: identical
    content is reused, different content gets the position as a prefix), its EXIF read,
    ``session.yaml`` saved and the change logged; returns the session as saved.
    ``origin`` is what session.yaml records as the frame's ``source``; by default the
    file's absolute path as given, written out (:func:`rigkit.core.tables.visible`; a
    file rigkit made itself says so instead, e.g. ``rendered by rigkit synth, seed 7``,
    which does not depend on the machine). A name that holds characters no name should
    (control, invisible, not UTF-8) is stored under :func:`stored_name`."""
    session, position, source = staged.session, staged.position, staged.source
    assert staged.copy is not None, "a staged frame is filed inside staged_frame's block"
    stored = _store(session.path / RAW_DIR, staged.copy, stored_name(source.name), position)
    frame = Frame(
        position=position,
        file=f"{RAW_DIR}/{stored}",
        sha256=staged.sha256,
        size_px=staged.size,
        added_utc=utc_now(),
        source=origin or visible(str(source.resolve()), lines=False),
        exif=exif_fields(read_exif(staged.path)),
    )
    before = () if staged.replace_existing else session.bursts.get(position, ())
    updated = replace(session, bursts={**session.bursts, position: (*before, frame)})
    save_session(updated)
    log_event(session.path, "add-frame",
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


def stored_name(name: str) -> str:
    """The name a frame file called ``name`` gets in ``raw/``: every character that is
    no plain printable one (control characters, a newline, an escape, Unicode's
    invisible and direction-changing ones) and every byte of the name that is not UTF-8
    made ``_``, so nothing in ``session.yaml``, ``history.log`` or on a screen can be
    turned against the reader (the original is recorded as the frame's ``source``)."""
    text = os.fsencode(name).decode("utf-8", "replace").replace("\ufffd", "_")
    return "".join(c if c.isprintable() else "_" for c in text)


def _check_joins(session: Session, position: str, source: Path, staged: Path,
                 sha256: str, replace_existing: bool, burst: bool) -> None:
    """InputError naming ``source`` where ``staged`` (its copy, SHA-256 ``sha256``) cannot
    join ``position``'s frames: it has some and neither ``burst`` nor
    ``replace_existing`` says how, or the frames would not make a capture
    (:func:`rigkit.capture.frames.capture_problems`: a frame twice, RAW mixed in)."""
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
    done = session_comparisons(path)
    if not done.is_file():
        return
    try:
        rows = read_rows(done)
    except InputError:  # derived and damaged: the next run replaces it; it blocks nothing
        return
    log = path / LOG_NAME
    damaged: list[str] = []  # said by what reads the log; the repair needs the run ids
    try:
        logged = {row.run_id for row in read_rows(log, damaged)} if log.is_file() else set()
    except InputError:  # no log that can be read (too large, no CSV): its readers say so
        return
    missing = [row for row in rows if row.run_id not in logged]
    if missing:
        append_rows(log, missing)
        log_event(path, "repair", f"run {missing[0].run_id}: its {len(missing)} rows appended "
                  "to the comparisons log after an interrupted run")


def session_frames(session: Session) -> dict[str, tuple[FrameFile, ...]]:
    """The session's frames as the depth run takes them (position -> its burst)."""
    return {pos: tuple(FrameFile(session.path / f.file, f.sha256, f.file) for f in burst)
            for pos, burst in session.bursts.items()}


_INGEST_LEFTOVER = re.compile(r"\.ingest\..*\.tmp")
"""The partial copies an older rigkit made inside ``raw/`` (before it staged outside)."""


def clean_staging(session_path: Path) -> None:
    """Remove what an interrupted ``add-frame`` left: staged copies, and the partial
    copies (``raw/.ingest.*.tmp``) that rigkit made inside ``raw/`` before it staged
    outside it. Called under the session's lock, when no copy can be under way. Each
    folder is opened once, without following a link, and emptied relative to its
    descriptor (:func:`rigkit.core.safefs.remove_files`): a ``.staging`` swapped for a
    link to ``raw/`` or elsewhere during the cleanup has nothing removed from it."""
    leftovers: dict[str, Callable[[str], bool]] = {
        STAGING_DIR: lambda _: True, RAW_DIR: lambda n: _INGEST_LEFTOVER.fullmatch(n) is not None}
    for name, match in leftovers.items():
        try:
            folder = open_folder(session_path / name)
        except FileNotFoundError:
            continue
        try:
            remove_files(folder, match)
        finally:
            os.close(folder)


@dataclass(frozen=True)
class _Staged:
    """A frame's copy in the session's staging folder: ``folder`` the folder's
    descriptor, ``name`` the copy's name in it, ``path`` a path that reaches the copy
    through the descriptor (:func:`rigkit.core.safefs.fd_path`), ``sha256`` of exactly
    the bytes copied."""

    folder: int
    name: str
    path: Path
    sha256: str


@contextmanager
def _staged(session_path: Path, source: Path) -> Iterator[_Staged]:
    """A byte-for-byte copy of ``source`` (never a FIFO or a device) in the session's
    staging folder (outside ``raw/``), fsynced; removed afterwards, whatever happens (a
    frame that is kept has been linked into ``raw/`` by then). The staging folder is
    opened once and the copy made, read and removed relative to it."""
    staging = session_path / STAGING_DIR
    try:
        folder = open_folder(staging, create=True)
    except OSError as exc:
        raise InputError(f"{session_path}: cannot write to the session ({exc.strerror})"
                         ) from None
    name = f".frame.{secrets.token_hex(8)}{source.suffix}"  # the decoder goes by the suffix
    try:
        out = os.open(name, os.O_WRONLY | os.O_CREAT | os.O_EXCL | os.O_NOFOLLOW | os.O_CLOEXEC,
                      0o666, dir_fd=folder)
        digest, copied = hashlib.sha256(), 0
        with os.fdopen(out, "wb") as copy, os.fdopen(open_input(source), "rb") as original:
            for block in iter(lambda: original.read(1 << 20), b""):
                copied += len(block)
                if copied > MAX_FRAME_BYTES:  # it grew past any frame while copied
                    raise too_large(source, copied, MAX_FRAME_BYTES, "a frame file")
                digest.update(block)
                copy.write(block)
            copy.flush()
            os.fsync(copy.fileno())
        yield _Staged(folder, name, fd_path(folder, name, staging), digest.hexdigest())
    finally:
        with suppress(FileNotFoundError):
            os.unlink(name, dir_fd=folder)
        os.close(folder)


def _store(raw_dir: Path, staged: _Staged, name: str, position: str) -> str:
    """Link the accepted ``staged`` copy into ``raw_dir`` without overwriting anything:
    under its original ``name``, or prefixed with the position when a different file
    already has that name. Returns the name stored. ``raw/`` is opened once (a link to
    a folder elsewhere is refused) and linked into relative to its descriptor, from the
    staging folder's, so a folder swapped for a link meanwhile redirects nothing."""
    folder = open_folder(raw_dir, create=True)
    try:
        for candidate in (name, f"{position}-{name}"):
            try:  # fails rather than overwrite a file that appeared meanwhile
                os.link(staged.name, candidate, src_dir_fd=staged.folder, dst_dir_fd=folder,
                        follow_symlinks=False)
            except FileExistsError:
                if _same_file(folder, candidate, staged.sha256):
                    return candidate
                continue
            os.fsync(folder)
            return candidate
    finally:
        os.close(folder)
    raise InputError(
        f"{raw_dir}: already holds different files named {name} and {position}-{name}; "
        "rename the file to add"
    )


def _same_file(folder: int, name: str, sha256: str) -> bool:
    """Whether ``name`` in the folder open at ``folder`` is a regular file (not a link,
    not a FIFO) holding the bytes of SHA-256 ``sha256``."""
    try:
        return fd_sha256(open_regular(Path(name), os.O_RDONLY, dir_fd=folder)) == sha256
    except (OSError, InputError):
        return False


def exif_fields(info: ExifInfo) -> dict[str, Any]:
    """The EXIF fields worth keeping in session.yaml (absent ones left out)."""
    keep = (
        "make", "model", "focal_length_mm", "focal_length_35mm_mm", "exposure_time_s",
        "f_number", "iso", "datetime_original",
    )
    return {name: getattr(info, name) for name in keep if getattr(info, name) is not None}


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
                there = path.lstat().st_mode if path.exists() else None
                problems.append(f"{position} frame {frame.file} is "
                                + ("missing" if there is None else
                                   f"{kind_of(there)}, not the frame file"))
            elif file_sha256(path) != frame.sha256:
                problems.append(
                    f"{position} frame {frame.file} no longer matches the hash recorded at "
                    "ingest (the original was changed)"
                )
            elif frame.size_px != size:
                problems.append(
                    f"{position} frame {frame.file} is {frame.size_px[0]}x{frame.size_px[1]}"
                    f" px as session.yaml records it, the rig's image size {size[0]}x"
                    f"{size[1]} px"
                )
    for target in session.targets:
        try:
            check_target_inside(session, target)
        except InputError as exc:
            problems.append(str(exc).split(": ", 1)[1])
    return problems
