"""The one rule for files rigkit opens inside a folder it does not trust (a session
copied from a card, synced from a laptop, unpacked from an archive), as careful archive
tools treat what they unpack:

* a file rigkit writes, appends to, locks or reads there is opened without following
  a symbolic link (``O_NOFOLLOW``) and without blocking (``O_NONBLOCK``), and must turn
  out to be a regular file: never a link to a frame or to ``/etc``, a FIFO that would
  hang the command, or a device such as ``/dev/zero``;
* a folder rigkit owns there (``raw/``, ``.staging``, ``results/``, ``derived/``) must
  be a real folder, not a link to one elsewhere, before anything is stored in it or
  deleted from it.

Anything else is refused with :class:`~rigkit.errors.InputError`, one line naming the
path and what it is, before a byte is written or deleted. Tests:
``tests/core/test_safefs.py`` and ``tests/capture/test_hostile_session.py``.
"""

from __future__ import annotations

import contextlib
import errno
import fcntl
import os
import stat
from collections.abc import Callable
from pathlib import Path

from rigkit.errors import InputError

_KINDS = {stat.S_IFLNK: "a symbolic link", stat.S_IFIFO: "a FIFO", stat.S_IFCHR: "a device",
          stat.S_IFBLK: "a device", stat.S_IFSOCK: "a socket", stat.S_IFDIR: "a folder"}


def kind_of(mode: int) -> str:
    """What a file of ``st_mode`` is, in words ("a FIFO", "a regular file")."""
    return _KINDS.get(stat.S_IFMT(mode), "a regular file")


def refusal(path: Path, what: str) -> InputError:
    """The one line for a path that is not what rigkit may use there."""
    return InputError(f"{path}: is {what}, not a regular file; rigkit does not follow links "
                      "or open special files inside a session (remove it)")


def open_regular(path: Path, flags: int, mode: int = 0o666, dir_fd: int | None = None) -> int:
    """``os.open`` of ``path`` (relative to the folder open at ``dir_fd``, where given)
    that refuses a symbolic link, a FIFO, a device or a folder (InputError naming it); a
    descriptor of a regular file otherwise, in blocking mode. Other failures (a missing
    file without ``O_CREAT``, no permission) raise OSError."""
    try:
        fd = os.open(path, flags | os.O_NOFOLLOW | os.O_NONBLOCK | os.O_CLOEXEC, mode,
                     dir_fd=dir_fd)
    except OSError as exc:
        if exc.errno == errno.ELOOP:
            raise refusal(path, "a symbolic link") from None
        if exc.errno in (errno.ENXIO, errno.EISDIR, errno.ENODEV):
            raise refusal(path, _lkind(path, dir_fd)) from None
        raise
    info = os.fstat(fd)
    if not stat.S_ISREG(info.st_mode):
        os.close(fd)
        raise refusal(path, kind_of(info.st_mode))
    fcntl.fcntl(fd, fcntl.F_SETFL, fcntl.fcntl(fd, fcntl.F_GETFL) & ~os.O_NONBLOCK)
    return fd


def read_regular(path: Path, limit: int, what: str = "this file",
                 dir_fd: int | None = None) -> bytes:
    """The bytes of the regular file ``path`` (:func:`open_regular`'s rule; relative to
    the folder open at ``dir_fd``, where given), at most ``limit`` of them: a larger file
    is refused (:func:`too_large`, ``what`` saying what it should be) before it is
    read."""
    return _read_bounded(open_regular(path, os.O_RDONLY, dir_fd=dir_fd), path, limit, what)


def too_large(path: Path, size: int, limit: int, what: str) -> InputError:
    """The one line for a file larger than what it is read as can be."""
    return InputError(f"{path}: {_amount(size)}, more than the {_amount(limit)} {what} can "
                      "be; not read (is it the right file?)")


def open_input(path: Path) -> int:
    """A descriptor for reading the file ``path`` that the user named (links followed):
    a regular file, else InputError saying what it is (no such file, a folder, a FIFO, a
    device) before it is opened, and checked again on the open descriptor, which was
    opened without blocking (a FIFO swapped in meanwhile would hang the read)."""
    require_file(path)
    try:
        fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK | os.O_CLOEXEC)
    except FileNotFoundError:
        raise InputError(f"{path}: no such file") from None
    except OSError as exc:
        raise InputError(f"{path}: cannot read ({exc.strerror or exc})") from None
    info = os.fstat(fd)
    if not stat.S_ISREG(info.st_mode):
        os.close(fd)
        raise InputError(f"{path}: is {kind_of(info.st_mode)}, not a file")
    fcntl.fcntl(fd, fcntl.F_SETFL, fcntl.fcntl(fd, fcntl.F_GETFL) & ~os.O_NONBLOCK)
    return fd


def read_input(path: Path, limit: int, what: str = "this file") -> bytes:
    """The bytes of the file ``path`` the user named (:func:`open_input`), at most
    ``limit`` (:func:`too_large` otherwise, before it is read)."""
    return _read_bounded(open_input(path), path, limit, what)


def _read_bounded(fd: int, path: Path, limit: int, what: str) -> bytes:
    with os.fdopen(fd, "rb") as handle:
        size = os.fstat(fd).st_size
        if size > limit:
            raise too_large(path, size, limit, what)
        data = handle.read(limit + 1)
    if len(data) > limit:  # it grew while read
        raise too_large(path, len(data), limit, what)
    return data


def _amount(size: int) -> str:
    """A number of bytes in words: ``3.0 GB``, ``64 MB``, ``900 bytes``."""
    for unit, scale in (("GB", 2**30), ("MB", 2**20), ("KB", 2**10)):
        if size >= scale:
            return f"{size / scale:.3g} {unit}"
    return f"{size} bytes"


def require_file(path: Path) -> None:
    """InputError naming ``path``, a file the user named (links followed), unless it is
    a regular file: "no such file", or what it is instead (a folder, a FIFO, a device)."""
    try:
        info = os.stat(path)
    except FileNotFoundError:
        raise InputError(f"{path}: no such file") from None
    except OSError as exc:
        raise InputError(f"{path}: cannot read ({exc.strerror or exc})") from None
    if not stat.S_ISREG(info.st_mode):
        raise InputError(f"{path}: is {kind_of(info.st_mode)}, not a file")


def check_regular(path: Path) -> None:
    """InputError where ``path`` exists and is no regular file (:func:`open_regular`'s
    rule): said before long work that will append to it, not after its results."""
    try:
        info = os.lstat(path)
    except FileNotFoundError:
        return
    if not stat.S_ISREG(info.st_mode):
        raise refusal(path, kind_of(info.st_mode))


def real_folder(path: Path, create: bool = False) -> Path:
    """``path`` if it is a real folder (not a link to one; made first with ``create``);
    InputError naming it otherwise. FileNotFoundError where it is missing and not made."""
    if create:
        try:
            path.mkdir()
        except FileExistsError:
            pass
    info = os.lstat(path)
    if not stat.S_ISDIR(info.st_mode):
        raise InputError(f"{path}: is {kind_of(info.st_mode)}, not a folder; rigkit keeps its "
                         "own folders inside the session and does not follow links (remove it)")
    return path


def open_folder(path: Path, create: bool = False) -> int:
    """A descriptor of the real folder ``path`` (made first with ``create``), opened
    without following a link, to work inside it relative to the descriptor (``dir_fd``,
    ``os.scandir``): the folder stays the one checked even if its name is swapped for a
    link meanwhile. InputError naming it where it is a link or no folder (the rule of
    :func:`real_folder`); FileNotFoundError where it is missing and not made."""
    if create:
        try:
            os.mkdir(path)
        except FileExistsError:
            pass
    try:
        return os.open(path, os.O_RDONLY | os.O_DIRECTORY | os.O_NOFOLLOW | os.O_CLOEXEC)
    except FileNotFoundError:
        raise
    except OSError as exc:
        if exc.errno not in (errno.ELOOP, errno.ENOTDIR):
            raise
    real_folder(Path(path))  # says what it is
    raise InputError(f"{path}: changed while it was opened")


def remove_files(folder_fd: int, match: Callable[[str], bool]) -> None:
    """Remove the regular files whose names ``match`` from the folder open at
    ``folder_fd``: listed on the descriptor, each judged without following a link and
    removed relative to the descriptor, so a folder swapped for a link meanwhile (to
    ``raw/``, to somewhere else) has nothing removed from it; a link found inside is
    left alone."""
    with os.scandir(folder_fd) as entries:
        for entry in entries:
            if match(entry.name) and entry.is_file(follow_symlinks=False):
                with contextlib.suppress(FileNotFoundError, IsADirectoryError):
                    os.unlink(entry.name, dir_fd=folder_fd)


def fd_path(folder_fd: int, name: str, folder: Path) -> Path:
    """A path to ``name`` inside ``folder``, open at ``folder_fd``, that resolves through
    the descriptor (Linux's ``/proc/self/fd``), for code that opens files by path (a
    decoder): it reads the file in that folder even if the folder's own name was
    swapped for a link meanwhile. ``folder / name`` where the system has no such
    paths."""
    through = Path(f"/proc/self/fd/{folder_fd}")
    return through / name if through.is_dir() else Path(folder) / name


def _lkind(path: Path, dir_fd: int | None = None) -> str:
    try:
        return kind_of(os.lstat(path, dir_fd=dir_fd).st_mode)
    except OSError:
        return "not a regular file"
