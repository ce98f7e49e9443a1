"""Writing files so that readers see the old version or the new one, never half.

Every write goes to a hidden temporary file with a unique name in the target's own
folder (so the final rename stays on one file system), is flushed and fsynced, and is
then renamed over the target with :func:`os.replace`. A failure removes the temporary
file and leaves the target as it was.

Three granularities:

* one file: :func:`write_text`, :func:`write_bytes`, :func:`write_png`,
  :func:`write_npy`, or :func:`write_file` choosing by content and suffix;
* several files in one folder: :func:`write_together` stages them all in a hidden
  folder first, so a failure never leaves a mix of old and new outputs;
  :func:`staged_files` does the same for files written by streaming writers;
* a whole folder: :func:`replace_folder` stages a new folder, retires the current one,
  renames the staged one in and deletes the retired one; :func:`recover_folder`
  undoes what a crash in the middle of that left behind.
"""

from __future__ import annotations

import contextlib
import hashlib
import os
import secrets
import shutil
import stat
import tempfile
from collections.abc import Callable, Iterable, Iterator, Mapping
from pathlib import Path
from typing import BinaryIO

import numpy as np

from rigkit.core.safefs import open_input, open_regular
from rigkit.errors import InputError

#: What :func:`write_file` writes: text (UTF-8), bytes, or an array (``.png``: BGR or
#: grey uint8/uint16; ``.npy``: any array).
Content = str | bytes | np.ndarray

_RETIRED = "old"


def file_sha256(path: Path) -> str:
    """Hex SHA-256 of a file's bytes, read in 1 MiB blocks; InputError naming the file
    when it is no regular file (:func:`rigkit.core.safefs.open_input`) or cannot be
    read."""
    try:
        return fd_sha256(open_input(Path(path)))  # never a FIFO or a device
    except OSError as exc:
        raise InputError(f"{path}: cannot read ({exc.strerror or exc})") from None


def fd_sha256(fd: int) -> str:
    """Hex SHA-256 of the bytes of the file open at ``fd`` from where it stands, read in
    1 MiB blocks; the descriptor is closed. OSError if it cannot be read."""
    digest = hashlib.sha256()
    with os.fdopen(fd, "rb") as handle:
        for block in iter(lambda: handle.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()


def append_whole(path: Path, text: str) -> None:
    """Append ``text`` (whole lines, UTF-8) to the log at ``path``: it lands whole or not
    at all. The file's size is noted first; a write that fails part way (a full disk)
    is truncated back to it, so no half line is left for the next append to glue onto.
    A file that does not end with a newline (a torn line from a crash mid-write) gets
    one first, leaving that fragment a line of its own. OSError if the write fails."""
    data = text.encode("utf-8")
    fd = open_regular(path, os.O_RDWR | os.O_APPEND | os.O_CREAT)  # never a link or a FIFO
    try:
        size = os.fstat(fd).st_size
        if size and os.pread(fd, 1, size - 1) != b"\n":
            data = b"\n" + data
        try:
            written = 0
            while written < len(data):
                written += os.write(fd, data[written:])
            os.fsync(fd)
        except OSError:
            with contextlib.suppress(OSError):
                os.ftruncate(fd, size)
            raise
    finally:
        os.close(fd)


def check_writable_folder(folder: Path, what: str) -> None:
    """Create ``folder`` if need be and make sure files can be written in it, before
    long work whose result would go there; InputError naming ``what`` otherwise."""
    folder = Path(folder)
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except FileExistsError:
        raise InputError(f"{what}: {folder} is a file, not a folder") from None
    except OSError as exc:
        raise InputError(f"{what}: cannot create {folder} ({exc.strerror})") from None
    if not os.access(folder, os.W_OK | os.X_OK):
        raise InputError(f"{what}: cannot write in {folder} (permission denied or read-only)")


def check_creatable(path: Path, what: str) -> None:
    """InputError naming ``what`` where the file ``path`` could not be written there:
    something other than a file by that name (a folder, a FIFO, a device), or no folder
    it could be made in (the nearest existing one on its way is a file, or cannot be
    written). Creates nothing, so a command refused afterwards leaves no folder behind;
    its folders are made when it writes."""
    path = Path(path)
    if os.path.lexists(path) and not path.is_symlink() and not path.is_file():
        kind = "a folder" if path.is_dir() else "not a regular file"
        raise InputError(f"{what}: {path} is {kind}; name a file to write")
    folder = path.parent
    while not os.path.lexists(folder) and folder != folder.parent:
        folder = folder.parent
    if not folder.is_dir():
        raise InputError(f"{what}: {folder} is a file, not a folder")
    if not os.access(folder, os.W_OK | os.X_OK):
        raise InputError(f"{what}: cannot write in {folder} (permission denied or read-only)")


def replaced_entry(path: Path) -> str:
    """The folder entry that writing ``path`` replaces: its folder with every link
    resolved, and its own name as it is (a write renames a new file over that name, so
    a link there is replaced, not followed)."""
    path = Path(path)
    return os.path.join(os.path.realpath(path.parent), path.name)


def check_not_inputs(outputs: Iterable[Path], inputs: Iterable[Path], what: str) -> None:
    """InputError naming ``what`` where writing one of ``outputs`` would replace one of
    ``inputs``, before any work: a command never writes over a file it reads. An
    input's data lies at its real path (every link resolved), which is what a write of
    the same entry would destroy; another hard link to it keeps the old data, since
    writes rename a new file into place."""
    read = {os.path.realpath(p): Path(p) for p in inputs}
    for out in outputs:
        source = read.get(replaced_entry(out))
        if source is not None:
            raise InputError(f"{what}: writing {out} would replace the input {source}; "
                             "choose another name")


def check_free_space(folder: Path, needed_bytes: int, what: str) -> None:
    """InputError naming ``what`` when ``folder``'s file system has less than
    ``needed_bytes`` free, before long work whose output would not fit."""
    try:
        stats = os.statvfs(folder)
    except OSError:
        return  # cannot tell: the write itself will say
    free = stats.f_bavail * stats.f_frsize
    if free < needed_bytes:
        raise InputError(f"{what}: needs about {needed_bytes / 2**20:,.0f} MB free in {folder},"
                         f" has {free / 2**20:,.0f} MB (the disk is nearly full)")


def temp_file(folder: Path, name: str) -> tuple[int, Path]:
    """A new, empty, hidden file ``.<name>.<random>.tmp`` in ``folder``, opened for
    writing (the descriptor and its path), with the usual permissions (0666 less the
    umask; ``tempfile.mkstemp`` would make it private)."""
    while True:
        path = Path(folder) / f".{name}.{secrets.token_hex(4)}.tmp"
        try:
            return os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o666), path
        except FileExistsError:
            continue


def write_with(path: Path, dump: Callable[[BinaryIO], object]) -> None:
    """Replace ``path`` atomically with what ``dump(handle)`` writes to a binary handle."""
    path = Path(path)
    fd, tmp = temp_file(path.parent, path.name)
    try:
        with os.fdopen(fd, "wb") as handle:
            dump(handle)
            handle.flush()
            os.fsync(handle.fileno())
        os.replace(tmp, path)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise


def write_at(folder_fd: int, name: str, data: bytes) -> None:
    """Replace ``name`` in the folder open at ``folder_fd`` with ``data`` atomically, as
    :func:`write_bytes` does, every step relative to the descriptor (the temporary
    file created without following a link): a folder of an untrusted session swapped
    for a link meanwhile does not redirect the write."""
    while True:
        tmp = f".{name}.{secrets.token_hex(4)}.tmp"
        try:
            fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL | os.O_NOFOLLOW | os.O_CLOEXEC,
                         0o666, dir_fd=folder_fd)
            break
        except FileExistsError:
            continue
    try:
        with os.fdopen(fd, "wb") as handle:
            handle.write(data)
            handle.flush()
            os.fsync(handle.fileno())
        os.replace(tmp, name, src_dir_fd=folder_fd, dst_dir_fd=folder_fd)
    except BaseException:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(tmp, dir_fd=folder_fd)
        raise


def write_bytes(path: Path, data: bytes) -> None:
    """Replace ``path`` with ``data`` atomically."""
    write_with(path, lambda handle: handle.write(data))


def write_text(path: Path, text: str) -> None:
    """Replace ``path`` with ``text`` (UTF-8) atomically."""
    write_bytes(path, text.encode("utf-8"))


def encode_png(img: np.ndarray, compression: int | None = None) -> bytes:
    """PNG bytes of a BGR or grey image (uint8 or uint16); OSError if OpenCV cannot
    encode it. ``compression`` 0-9, None for OpenCV's default."""
    import cv2

    params = [] if compression is None else [cv2.IMWRITE_PNG_COMPRESSION, compression]
    ok, encoded = cv2.imencode(".png", img, params)
    if not ok:
        raise OSError(f"cannot encode a {img.shape} {img.dtype} image as PNG")
    return encoded.tobytes()


def write_png(path: Path, img: np.ndarray, compression: int | None = None) -> None:
    """Replace ``path`` with ``img`` as PNG atomically."""
    write_bytes(path, encode_png(img, compression))


def write_npy(path: Path, array: np.ndarray) -> None:
    """Replace ``path`` with ``array`` in NumPy's ``.npy`` format atomically."""
    write_with(path, lambda handle: np.save(handle, array))


NPY_MAGIC = b"\x93NUMPY"
"""How every NumPy array file (.npy) begins."""


def read_npy(path: Path) -> np.ndarray:
    """The array in the .npy file ``path``, mapped rather than read (its header says its
    size before any of it is read); FileNotFoundError where there is none, InputError
    naming the file where it is no array file or a damaged one. Any other file made
    NumPy suggest loading it as a pickle, which rigkit never does."""
    try:
        with os.fdopen(open_input(Path(path)), "rb") as handle:
            head = handle.read(len(NPY_MAGIC))
    except IsADirectoryError:
        raise InputError(f"{path}: a folder, not a NumPy array file (.npy)") from None
    if head != NPY_MAGIC:
        raise InputError(f"{path}: not a NumPy array file (.npy)")
    try:
        array = np.load(path, mmap_mode="r", allow_pickle=False)
    except (OSError, ValueError) as exc:
        raise InputError(f"{path}: a damaged NumPy array file ({exc})") from None
    if not isinstance(array, np.ndarray):
        raise InputError(f"{path}: not a NumPy array file (.npy)")
    return array


def _dump(path: Path, content: Content) -> Callable[[BinaryIO], object]:
    """How to write ``content`` to ``path``: by type, and for arrays by suffix."""
    if isinstance(content, str):
        data = content.encode("utf-8")
        return lambda handle: handle.write(data)
    if isinstance(content, bytes):
        return lambda handle: handle.write(content)
    if path.suffix == ".png":
        png = encode_png(content)
        return lambda handle: handle.write(png)
    if path.suffix == ".npy":
        return lambda handle: np.save(handle, content)
    raise ValueError(f"{path}: no writer for an array with this suffix")


def write_file(path: Path, content: Content) -> None:
    """Replace ``path`` atomically with text, bytes, or an array as ``.png``/``.npy``."""
    write_with(path, _dump(Path(path), content))


def _write_new(path: Path, content: Content) -> None:
    """Write a file that nobody reads yet (inside a staging folder): write and fsync."""
    dump = _dump(path, content)
    with path.open("xb") as handle:
        dump(handle)
        handle.flush()
        os.fsync(handle.fileno())


def fsync_folder(folder: Path) -> None:
    """Make renames inside ``folder`` durable (best effort: not every system allows it)."""
    with contextlib.suppress(OSError):
        fd = os.open(folder, os.O_RDONLY)
        try:
            os.fsync(fd)
        finally:
            os.close(fd)


def write_together(folder: Path, files: Mapping[str, Content],
                   check: Callable[[Path], None] | None = None) -> None:
    """Write ``files`` (name -> content) into ``folder``: all of them into a hidden
    temporary folder inside it first, then each renamed into place, so a failure never
    leaves a mix of old and new outputs that looks complete. OSError if a write fails;
    nothing temporary is left behind either way. The files are encoded and written
    side by side (:class:`rigkit.core.threads.ViewPool`: a PNG is compressed while an
    array is written); the first failure in ``files``' order is raised. ``check``: as
    for :func:`staged_files`."""
    from rigkit.core.threads import ViewPool

    with staged_files(folder, check) as tmp, ViewPool() as pool:
        pool.map(_write_new, [tmp / name for name in files], files.values())


@contextlib.contextmanager
def staged_files(folder: Path, check: Callable[[Path], None] | None = None
                 ) -> Iterator[Path]:
    """A hidden temporary folder inside ``folder`` to write several files into (streamed,
    by any writer); when the block ends normally each file is fsynced and renamed into
    ``folder``, replacing any of the same name. If the block raises, the temporary
    folder and everything in it is removed and ``folder`` is left as it was.
    ``check(target)``, called for every target before the first rename, may refuse the
    lot by raising (:mod:`rigkit.core.outputs`: a file that appeared meanwhile)."""
    folder = Path(folder)
    _remove_stale_staging(folder)
    with tempfile.TemporaryDirectory(dir=folder, prefix=f"{STAGING_PREFIX}{os.getpid()}-") as tmp:
        (Path(tmp) / STAGING_MARK).write_bytes(b"")
        yield Path(tmp)
        staged = sorted(p for p in Path(tmp).iterdir() if p.name != STAGING_MARK)
        for path in staged:
            _fsync_file(path)
            if check is not None:
                check(folder / path.name)
        for path in staged:
            os.replace(path, folder / path.name)
    fsync_folder(folder)


STAGING_PREFIX = ".rigkit-"
"""Staging folders of :func:`staged_files` are named ``.rigkit-<pid>-<random>``."""
STAGING_MARK = ".rigkit-staging"
"""The empty file :func:`staged_files` puts in each staging folder first: a folder of
that name without it is someone else's, and is never removed."""


def _remove_stale_staging(folder: Path) -> None:
    """Remove staging folders that :func:`staged_files` left in ``folder`` in a process
    that no longer runs (killed before it could clean up); another live process's are
    left alone."""
    for stale in folder.glob(f"{STAGING_PREFIX}*-*"):
        pid = stale.name[len(STAGING_PREFIX):].split("-", 1)[0]
        if not pid.isdigit() or _alive(int(pid)) or stale.is_symlink() or not stale.is_dir():
            continue
        mark = stale / STAGING_MARK
        if mark.is_symlink() or not mark.is_file():  # a folder of someone's: kept (a user's
            continue  # ".rigkit-99999-backup" was removed with what it held)
        shutil.rmtree(stale, ignore_errors=True)


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # another user's: alive
        return True
    return True


def _fsync_file(path: Path) -> None:
    fd = os.open(path, os.O_RDONLY)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)


def replace_folder(
    parent: Path, name: str, files: Mapping[str, Content], stage_id: str | None = None
) -> None:
    """Replace the folder ``parent/name`` as a whole by one holding exactly ``files``.

    The new folder is staged as ``.<name>-<stage_id>`` (a random id by default), the
    current one is renamed to ``.<name>-old-<stage_id>``, the staged one renamed in and
    the retired one deleted. Readers see the old folder or the new one; a crash leaves
    something :func:`recover_folder` repairs (it runs first here too). On a failure
    before the swap, the staged folder is removed and the current one is untouched.
    Every step is taken relative to ``parent``'s descriptor, and the files are written
    through the staged folder's, never following a link: ``parent`` may be a session
    from someone else, and a folder swapped for a link meanwhile redirects nothing.
    """
    parent = Path(parent)
    recover_folder(parent, name)
    stage_id = stage_id or secrets.token_hex(4)
    staging, retired = f".{name}-{stage_id}", f".{name}-{_RETIRED}-{stage_id}"
    folder = os.open(parent, os.O_RDONLY | os.O_DIRECTORY | os.O_CLOEXEC)
    try:
        os.mkdir(staging, dir_fd=folder)
        try:
            staged = os.open(staging, os.O_RDONLY | os.O_DIRECTORY | os.O_NOFOLLOW | os.O_CLOEXEC,
                             dir_fd=folder)
            try:
                for file_name, content in files.items():
                    _write_new_at(staged, file_name, content)
                os.fsync(staged)
            finally:
                os.close(staged)
            if _lexists_at(folder, name):
                os.rename(name, retired, src_dir_fd=folder, dst_dir_fd=folder)
            os.rename(staging, name, src_dir_fd=folder, dst_dir_fd=folder)
            with contextlib.suppress(OSError):
                os.fsync(folder)
        except BaseException:
            _remove_at(folder, staging)
            raise
        _remove_at(folder, retired)
    finally:
        os.close(folder)


def recover_folder(parent: Path, name: str) -> None:
    """Undo an interrupted :func:`replace_folder`: if ``parent/name`` is gone, restore
    the newest retired copy; then delete every staged or retired folder left over (a
    link among them is removed itself, never followed). Relative to ``parent``'s
    descriptor, as :func:`replace_folder` works."""
    folder = os.open(Path(parent), os.O_RDONLY | os.O_DIRECTORY | os.O_CLOEXEC)
    try:
        with os.scandir(folder) as entries:
            names = sorted(entry.name for entry in entries)
        retired = [n for n in names if n.startswith(f".{name}-{_RETIRED}-")]
        if name not in names and retired:
            os.rename(retired[-1], name, src_dir_fd=folder, dst_dir_fd=folder)
            names.remove(retired[-1])
        for leftover in names:
            if leftover.startswith(f".{name}-"):
                _remove_at(folder, leftover)
    finally:
        os.close(folder)


def _write_new_at(folder_fd: int, name: str, content: Content) -> None:
    """:func:`_write_new` of ``name`` in the folder open at ``folder_fd``."""
    dump = _dump(Path(name), content)
    fd = os.open(name, os.O_WRONLY | os.O_CREAT | os.O_EXCL | os.O_NOFOLLOW | os.O_CLOEXEC,
                 0o666, dir_fd=folder_fd)
    with os.fdopen(fd, "wb") as handle:
        dump(handle)
        handle.flush()
        os.fsync(handle.fileno())


def _lexists_at(folder_fd: int, name: str) -> bool:
    try:
        os.lstat(name, dir_fd=folder_fd)
    except FileNotFoundError:
        return False
    return True


def _remove_at(folder_fd: int, name: str) -> None:
    """Remove ``name`` from the folder open at ``folder_fd``, whatever it is (a folder
    with all it holds, without following a link inside; a link or file itself); best
    effort."""
    with contextlib.suppress(OSError):
        if stat.S_ISDIR(os.lstat(name, dir_fd=folder_fd).st_mode):
            shutil.rmtree(name, dir_fd=folder_fd, ignore_errors=True)
        else:
            os.unlink(name, dir_fd=folder_fd)
