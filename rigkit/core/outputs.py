"""The one rule for where a command may write: every output option (``--out``,
``--csv``, ``--output``, ``--raw-log``, a folder a command creates) and every file a
command writes into an output folder goes through it ([sessions.md](sessions.md),
"Where rigkit writes").

An output is never:

* inside a capture session's own parts: its ``raw/`` (the originals), ``derived/``,
  ``results/``, any hidden entry (``.staging/``, ``.lock``, ``.results-*``), nor onto
  its ``session.yaml`` or its logs (``history.log``, ``comparisons.csv``); a session is
  a folder holding ``session.yaml``, found by walking up from the output's real folder
  (links in the folders above resolved, so a link cannot hide a session);
* a symbolic link (rigkit does not write through links, nor replace them);
* a FIFO, a device, a socket or, for a file, a folder;
* a file that rigkit did not write. How rigkit knows its own files: each folder it
  writes outputs into keeps a ledger, :data:`LEDGER` (JSON), naming every file it
  wrote there with the file's inode, size and modification time as they were when it
  finished writing. A file is rigkit's while all three still match. A file someone
  made, copied over, edited or replaced since does not match and is refused, as is
  every file in a folder without a ledger (outputs of a rigkit older than the ledger
  included: remove them once). A log rigkit appends to is its own while its inode
  matches, it is no shorter than recorded and its first bytes are the ones recorded (a
  new file that took a removed log's inode is not). A command's ``--force`` (``rig
  calibrate``) only lets it replace such a file of its own;
* a file rigkit wrote as another product: each ledger entry names what wrote it
  (:data:`PRODUCTS`: a scene of ``rigkit synth``, the outputs of ``rigkit depth``, a
  report, an export, a rig profile, ...), and a command replaces only files of its own
  product. A scene's frames and ground truth are rigkit's, yet they are another
  command's inputs: ``rigkit depth --out`` onto a scene's ground truth, a depth
  preview onto another scene's frame, or a ``--raw-log`` onto a frame, were each
  written over them. Only a log is appended to.

Each refusal is :class:`~rigkit.errors.InputError`: one line naming the option, the
path and why, before any work. Files are written atomically (:mod:`rigkit.core.files`)
and checked again just before they are renamed into place, so a file that appears
meanwhile is not replaced either.
"""

from __future__ import annotations

import contextlib
import hashlib
import io
import json
import os
import stat
from collections.abc import Iterable, Iterator, Mapping
from pathlib import Path
from typing import Any

from rigkit.core.files import Content, staged_files, write_text, write_together
from rigkit.core.safefs import kind_of, open_regular, read_regular
from rigkit.errors import InputError

LEDGER = ".rigkit-outputs"
"""The file naming what rigkit wrote in a folder (see the module's docstring)."""
LEDGER_LIMIT = 4 << 20
"""The largest ledger read, bytes (some 30,000 files); a larger one counts as none."""
_FORMAT = "rigkit-outputs/1"
PRODUCTS = {
    "synth": "part of a scene that rigkit synth rendered (the other commands' input)",
    "depth": "an output of rigkit depth",
    "report": "a report of rigkit report",
    "export": "an export of rigkit export",
    "profile": "a rig profile that rigkit rig calibrate wrote",
    "eval": "an evaluation table of rigkit eval",
    "experiments": "an output of rigkit experiments",
    "readings": "a log of laser readings that rigkit rangefinder log appends to",
    "raw-log": "a log of serial traffic that --raw-log appends to",
}
LOGS = frozenset({"readings", "raw-log"})
"""The products rigkit appends to (:class:`OutputLog`), each only to its own kind."""
"""What may have written a file recorded in a ledger (its ``by``), as the refusals name
it; a command replaces only its own product's files."""

SESSION_FILE = "session.yaml"
"""A folder holding this is a capture session (:mod:`rigkit.capture.model`)."""
SESSION_KEPT = frozenset({SESSION_FILE, "raw", "derived", "results", "history.log",
                          "comparisons.csv"})
"""The entries of a session no output may be or be inside (hidden ones too): what the
session commands alone write. :mod:`rigkit.capture.model` names the same entries."""


def session_part(path: Path) -> tuple[Path, tuple[str, ...]] | None:
    """The session that ``path`` would be written in and where in it (its parts from
    the session folder down), where that is one of a session's own parts (``raw/...``,
    ``session.yaml``, a hidden entry); None elsewhere. ``path``'s folder is resolved
    (every link in it followed): what is checked is where the write lands."""
    entry = Path(os.path.realpath(Path(path).parent)) / Path(path).name
    for folder in entry.parents:  # every session around it: one may hold another
        if os.path.lexists(folder / SESSION_FILE):
            parts = entry.relative_to(folder).parts
            if parts[0] in SESSION_KEPT or parts[0].startswith("."):
                return folder, parts
    return None


def check_place(path: Path, what: str) -> None:
    """InputError naming ``what`` where ``path`` lies in a session's own parts, or is a
    folder's ledger."""
    if Path(path).name == LEDGER:
        raise InputError(f"{what}: {path} is where rigkit records what it wrote in that "
                         "folder; give another name")
    found = session_part(path)
    if found is not None:
        session, parts = found
        folder = os.path.isdir(session / parts[0]) or parts[0] in ("raw", "derived", "results")
        where = f"inside {parts[0]}/ of the session {session}" if len(parts) > 1 else \
            f"{parts[0]}/ of the session {session}" if folder else \
            f"the session {session}'s {parts[0]}"
        raise InputError(f"{what}: {path} is {where}, which only rigkit's session commands "
                         "write; write it elsewhere")


def check_output_file(path: Path, what: str, product: str | None = None) -> None:
    """InputError naming ``what`` unless a command may write the file ``path`` (a new
    one, or one rigkit wrote there whose inode, size and time still match its ledger,
    as ``product`` (:data:`PRODUCTS`; None: as any product, the command line's first
    look before the command says what it makes)): the module's rule."""
    path = Path(path)
    check_place(path, what)
    info = _lstat(path, what)
    if info is None:
        return
    if stat.S_ISLNK(info.st_mode):
        raise InputError(f"{what}: {path} is a symbolic link; rigkit writes through no "
                         "link: remove it or give another name")
    if not stat.S_ISREG(info.st_mode):
        raise InputError(f"{what}: {path} is {kind_of(info.st_mode)}, not a file rigkit "
                         "may write; give another name")
    entry = _ledger(path.parent).get(path.name)
    log = entry is not None and entry.get("by") in LOGS and entry.get("inode") == info.st_ino
    if not log and not _matches(entry, info):
        raise InputError(f"{what}: {path} exists and was not written by rigkit (or was "
                         f"changed since; see {LEDGER} in its folder): rigkit writes over "
                         "no file of yours; remove it or give another name")
    if log or (product is not None and entry is not None and entry.get("by") != product):
        raise InputError(f"{what}: {path} is {_described(entry)}, not this command's: "
                         "rigkit replaces only its own kind of output; give another name")


def check_output_folder(path: Path, what: str) -> None:
    """InputError naming ``what`` unless ``path`` may be a folder a command writes into
    or creates: not in a session's own parts, not a link, a folder where it exists."""
    path = Path(path)
    check_place(path, what)
    info = _lstat(path, what)
    if info is None:
        return
    if stat.S_ISLNK(info.st_mode):
        raise InputError(f"{what}: {path} is a symbolic link; rigkit writes through no "
                         "link: give the folder itself")
    if not stat.S_ISDIR(info.st_mode):
        raise InputError(f"{what}: {path} is {kind_of(info.st_mode)}, not a folder")


def check_output_log(path: Path, what: str, product: str | None = None) -> None:
    """InputError naming ``what`` unless rigkit may append to ``path``: a new file, or a
    regular file it created there as a log (its inode, size and first bytes in the
    ledger: :func:`_matches`), of ``product`` (:data:`LOGS`; None: of any)."""
    path = Path(path)
    check_place(path, what)
    info = _lstat(path, what)
    if info is None:
        return
    if stat.S_ISLNK(info.st_mode) or not stat.S_ISREG(info.st_mode):
        raise InputError(f"{what}: {path} is {kind_of(info.st_mode)}, not a log rigkit "
                         "may append to; give another name")
    try:
        fd = open_regular(path, os.O_RDONLY)
    except (OSError, InputError):
        fd = None
    entry = _ledger(path.parent).get(path.name)
    try:
        ours, a_log = _is_log(entry, info, fd, product), _is_log(entry, info, fd)
    finally:
        if fd is not None:
            os.close(fd)
    if not ours and (a_log or (entry is not None and _matches(entry, info))):
        raise InputError(f"{what}: {path} is {_described(entry)}, not this option's log: "
                         "rigkit appends only to a log of its own kind that it started; "
                         "give a new file")
    if not ours:
        raise InputError(f"{what}: {path} exists and is no log rigkit started (see "
                         f"{LEDGER} in its folder): rigkit appends to no file of yours; "
                         "give a new file")


def _lstat(path: Path, what: str) -> os.stat_result | None:
    """``path``'s own status (a link's, not its target's); None where nothing is there
    yet; InputError naming ``what`` where it cannot be there (its folder is a file)."""
    try:
        return os.lstat(path)
    except FileNotFoundError:
        return None
    except NotADirectoryError:
        raise InputError(f"{what}: {path}: {path.parent} is a file, not a folder") from None
    except OSError as exc:
        raise InputError(f"{what}: {path}: cannot look at it ({exc.strerror})") from None


CHECKS = {"file": check_output_file, "folder": check_output_folder, "log": check_output_log}
"""The check for each kind of output option (:mod:`rigkit.commands` declares them)."""


def check_outputs(folder: Path, names: Iterable[str], what: str,
                  product: str | None = None) -> None:
    """:func:`check_output_file` for each of ``names`` in ``folder``, as ``product``."""
    for name in names:
        check_output_file(Path(folder) / name, what, product)


def write_outputs(folder: Path, files: Mapping[str, Content], what: str,
                  product: str) -> None:
    """Write ``files`` (name -> content) into ``folder`` together
    (:func:`rigkit.core.files.write_together`) under the module's rule: each name is
    checked before and again just before its rename, and recorded in the ledger after,
    as ``product``'s (:data:`PRODUCTS`)."""
    folder = Path(folder)
    check_outputs(folder, files, what, product)
    write_together(folder, files, check=lambda path: check_output_file(path, what, product))
    record_outputs(folder, files, product)


@contextlib.contextmanager
def staged_outputs(folder: Path, names: Iterable[str], what: str,
                   product: str) -> Iterator[Path]:
    """:func:`rigkit.core.files.staged_files` for outputs: ``names`` (the files the
    block writes into the staging folder) checked before, and each again just before its
    rename; recorded in the ledger as ``product``'s when all are in place."""
    folder, names = Path(folder), list(names)
    check_outputs(folder, names, what, product)
    with staged_files(folder, check=lambda path: check_output_file(path, what, product)
                      ) as staging:
        yield staging
    record_outputs(folder, names, product)


class OutputLog(io.TextIOWrapper):
    """A log rigkit appends text to (``--output``, ``--raw-log``): a new file, recorded
    in its folder's ledger as rigkit's, or one recorded so before
    (:func:`check_output_log`); never a link, a FIFO or a device, and never blocking.
    Opened for reading too (``O_RDWR | O_APPEND``: a caller may look at its last byte
    through ``fileno()``); its state is recorded again when it is closed."""

    def __init__(self, path: Path, what: str, product: str, encoding: str = "utf-8") -> None:
        self.output_path, self.product = Path(path), product
        fd = _open_log(self.output_path, what, product)
        super().__init__(os.fdopen(fd, "ab"), encoding=encoding)

    def close(self) -> None:
        if not self.closed:
            super().close()
            record_outputs(self.output_path.parent, [self.output_path.name], self.product)


def _open_log(path: Path, what: str, product: str) -> int:
    check_output_log(path, what, product)
    flags = os.O_RDWR | os.O_APPEND
    try:
        fd = open_regular(path, flags | os.O_CREAT | os.O_EXCL)
    except FileExistsError:
        try:
            fd = open_regular(path, flags)
        except InputError as exc:
            raise InputError(f"{what}: {exc}") from None
        if not _is_log(_ledger(path.parent).get(path.name), os.fstat(fd), fd, product):
            os.close(fd)
            check_output_log(path, what, product)  # says why
            raise InputError(f"{what}: {path} changed while it was opened") from None
        return fd
    except InputError as exc:
        raise InputError(f"{what}: {exc}") from None
    except OSError as exc:
        raise InputError(f"{what}: cannot create {path} ({exc.strerror})") from None
    record_outputs(path.parent, [path.name], product)
    return fd


def record_outputs(folder: Path, names: Iterable[str], product: str) -> None:
    """Record ``names`` (regular files in ``folder``, just written) in the folder's
    ledger as ``product``'s (:data:`PRODUCTS`); a log (:data:`LOGS`) is a file rigkit
    appends to, known by its inode and first bytes. Read, changed and written under a
    lock on the folder, so that commands ending at once into one folder each keep their
    entries (16 runs side by side lost 10 of 80 without it). Best effort: a ledger that
    cannot be written leaves those files unclaimed, which only makes a later write over
    them refuse."""
    folder = Path(folder)
    with _folder_lock(folder):
        _record(folder, names, product)


@contextlib.contextmanager
def _folder_lock(folder: Path) -> Iterator[None]:
    """An exclusive lock on ``folder`` itself (flock on its descriptor) for as long as
    the block runs; none where the folder cannot be opened or locked."""
    import fcntl

    try:
        fd = os.open(folder, os.O_RDONLY | os.O_DIRECTORY | os.O_CLOEXEC)
    except OSError:
        yield
        return
    try:
        with contextlib.suppress(OSError):
            fcntl.flock(fd, fcntl.LOCK_EX)
        yield
    finally:
        os.close(fd)  # the lock goes with it


def _record(folder: Path, names: Iterable[str], product: str) -> None:
    ledger = _ledger(folder)
    for name in names:
        try:
            info = os.lstat(folder / name)
        except OSError:
            continue
        if not stat.S_ISREG(info.st_mode):
            continue
        ledger[name] = {"inode": info.st_ino, "size": info.st_size, "by": product}
        if product in LOGS:
            ledger[name]["head"] = _head(folder / name, info.st_size)
        else:
            ledger[name]["mtime_ns"] = info.st_mtime_ns
    text = json.dumps({"format": _FORMAT, "files": ledger}, indent=1, sort_keys=True)
    with contextlib.suppress(OSError):
        write_text(folder / LEDGER, text + "\n")


def _ledger(folder: Path) -> dict[str, dict[str, Any]]:
    """The ledger of ``folder``: name -> what was recorded; empty where there is none or
    it cannot be read (a link, a FIFO, damaged, too large): then nothing there is
    rigkit's."""
    try:
        data = json.loads(read_regular(Path(folder) / LEDGER, LEDGER_LIMIT))
    except (OSError, ValueError, InputError):
        return {}
    files = data.get("files") if isinstance(data, dict) and data.get("format") == _FORMAT \
        else None
    if not isinstance(files, dict):
        return {}
    return {name: entry for name, entry in files.items() if isinstance(entry, dict)}


def _described(entry: Mapping[str, Any] | None) -> str:
    """What wrote the file a ledger ``entry`` records, as a refusal names it."""
    return PRODUCTS.get(str((entry or {}).get("by")), "a file rigkit wrote")


def _is_log(entry: Mapping[str, Any] | None, info: os.stat_result, fd: int | None,
            product: str | None = None) -> bool:
    """Whether ``entry`` records a log (:func:`record_outputs`) of ``product`` (None: of
    any kind) and the file ``info`` and ``fd`` describe is still it (:func:`_matches`): a
    file rigkit wrote whole is no log to append to, nor is another option's log."""
    by = entry.get("by") if entry is not None else None
    return by in LOGS and (product is None or by == product) and _matches(entry, info, fd)


def _matches(entry: Mapping[str, Any] | None, info: os.stat_result,
             fd: int | None = None) -> bool:
    """Whether the file ``info`` describes is the one ``entry`` recorded: the same inode,
    size and time; a log (``head``): the same inode, at least the size recorded, and the
    same first bytes (``fd`` or the entry's folder to read them from), so a new file that
    took a removed log's inode is not taken for it."""
    if not entry or entry.get("inode") != info.st_ino:
        return False
    if "head" not in entry:
        return entry.get("size") == info.st_size and entry.get("mtime_ns") == info.st_mtime_ns
    size = entry.get("size")
    return isinstance(size, int) and info.st_size >= size and fd is not None \
        and _digest_head(fd, size) == entry["head"]


_HEAD = 4096
"""How many of a log's first bytes its ledger entry keeps a digest of."""


def _head(path: Path, size: int) -> str:
    """The digest of the first ``size`` (at most :data:`_HEAD`) bytes of the log at
    ``path``; "" where it cannot be read (then it is no log of rigkit's)."""
    try:
        fd = open_regular(path, os.O_RDONLY)
    except (OSError, InputError):
        return ""
    try:
        return _digest_head(fd, size)
    finally:
        os.close(fd)


def _digest_head(fd: int, size: int) -> str:
    return hashlib.sha256(os.pread(fd, min(size, _HEAD), 0)).hexdigest()
