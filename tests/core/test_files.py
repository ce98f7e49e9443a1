"""Atomic writes: single files, the staged multi-file write, the staged folder swap."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest

from rigkit.core import files
from rigkit.core.files import (
    recover_folder,
    replace_folder,
    temp_file,
    write_file,
    write_npy,
    write_png,
    write_text,
    write_together,
)


def test_single_files_by_kind(tmp_path: Path) -> None:
    write_text(tmp_path / "a.txt", "héllo\n")
    write_npy(tmp_path / "a.npy", np.arange(6, dtype=np.float32).reshape(2, 3))
    img = np.arange(48, dtype=np.uint8).reshape(4, 4, 3)
    write_png(tmp_path / "a.png", img)
    write_file(tmp_path / "b.bin", b"\x00\x01")
    assert (tmp_path / "a.txt").read_text(encoding="utf-8") == "héllo\n"
    assert np.load(tmp_path / "a.npy").tolist() == [[0, 1, 2], [3, 4, 5]]
    import cv2

    assert np.array_equal(cv2.imread(str(tmp_path / "a.png")), img)
    assert (tmp_path / "b.bin").read_bytes() == b"\x00\x01"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.npy", "a.png", "a.txt", "b.bin"]
    with pytest.raises(ValueError, match="no writer"):
        write_file(tmp_path / "a.jpg", img)


def test_temp_names_are_unique_hidden_and_in_the_target_folder(tmp_path: Path) -> None:
    opened = [temp_file(tmp_path, "session.yaml") for _ in range(50)]
    paths = {path for _, path in opened}
    for fd, _ in opened:
        os.close(fd)
    assert len(paths) == 50
    assert all(p.parent == tmp_path and p.name.startswith(".session.yaml.") for p in paths)
    assert all(p.suffix == ".tmp" for p in paths)


def test_a_failed_write_keeps_the_old_file_and_leaves_nothing(tmp_path: Path) -> None:
    target = tmp_path / "session.yaml"
    write_text(target, "old")

    def broken(handle) -> None:
        handle.write(b"half")
        raise OSError("disk full")

    with pytest.raises(OSError, match="disk full"):
        files.write_with(target, broken)
    assert target.read_text() == "old"
    assert [p.name for p in tmp_path.iterdir()] == ["session.yaml"]


def test_write_together_all_or_nothing(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    write_together(tmp_path, {"a.txt": "1", "b.npy": np.zeros(3)})
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.txt", "b.npy"]

    def broken(img: np.ndarray, compression: int | None = None) -> bytes:
        raise OSError("disk full")

    monkeypatch.setattr(files, "encode_png", broken)
    with pytest.raises(OSError, match="disk full"):
        write_together(tmp_path, {"a.txt": "2", "c.png": np.zeros((2, 2), np.uint8)})
    assert (tmp_path / "a.txt").read_text() == "1"  # the old file, not half a new set
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.txt", "b.npy"]


def test_replace_folder_swaps_the_whole_folder(tmp_path: Path) -> None:
    replace_folder(tmp_path, "results", {"a.txt": "1", "old-only.txt": "x"}, "run1")
    replace_folder(tmp_path, "results", {"a.txt": "2"}, "run2")
    assert sorted(p.name for p in (tmp_path / "results").iterdir()) == ["a.txt"]
    assert (tmp_path / "results" / "a.txt").read_text() == "2"
    assert [p.name for p in tmp_path.iterdir()] == ["results"]  # nothing staged or retired


def test_replace_folder_failure_keeps_the_current_folder(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    replace_folder(tmp_path, "results", {"a.txt": "1"}, "run1")

    def broken(img: np.ndarray, compression: int | None = None) -> bytes:
        raise OSError("disk full")

    monkeypatch.setattr(files, "encode_png", broken)
    with pytest.raises(OSError):
        replace_folder(tmp_path, "results", {"a.txt": "2", "p.png": np.zeros((2, 2))}, "run2")
    assert (tmp_path / "results" / "a.txt").read_text() == "1"
    assert [p.name for p in tmp_path.iterdir()] == ["results"]


@pytest.mark.parametrize("crash", ["after-retiring", "before-retiring"])
def test_recovery_after_an_interrupted_swap(tmp_path: Path, crash: str) -> None:
    replace_folder(tmp_path, "results", {"a.txt": "old"}, "run1")
    staged = tmp_path / ".results-run2"
    staged.mkdir()
    (staged / "a.txt").write_text("new, half written")
    if crash == "after-retiring":  # results/ renamed away, the staged one not yet in
        os.rename(tmp_path / "results", tmp_path / ".results-old-run2")
    recover_folder(tmp_path, "results")
    assert (tmp_path / "results" / "a.txt").read_text() == "old"
    assert [p.name for p in tmp_path.iterdir()] == ["results"]
    # The next swap starts from a clean folder.
    replace_folder(tmp_path, "results", {"a.txt": "new"}, "run3")
    assert (tmp_path / "results" / "a.txt").read_text() == "new"


def test_an_output_may_not_replace_an_input(tmp_path: Path) -> None:
    """The same entry, or the entry an input's links lead to, is refused; a link at the
    output's name, or another hard link to the input, is not (a write renames a new
    file over the name, and the input's data stays where it is)."""
    from rigkit.core.files import check_not_inputs
    from rigkit.errors import InputError

    frame = tmp_path / "frame.png"
    frame.write_bytes(b"captured")
    (tmp_path / "shots").mkdir()
    via = tmp_path / "shots" / "via.png"
    via.symlink_to(frame)
    folder_link = tmp_path / "same"
    folder_link.symlink_to(tmp_path)
    for out, given in ((frame, frame), (frame, via), (folder_link / "frame.png", frame)):
        with pytest.raises(InputError, match="would replace the input"):
            check_not_inputs([tmp_path / "other.npy", out], [given], "--out")
    hard = tmp_path / "hard.png"
    os.link(frame, hard)
    check_not_inputs([via, hard], [frame], "--out")
    write_together(tmp_path, {"hard.png": b"new"})
    write_together(tmp_path / "shots", {"via.png": b"new"})
    assert frame.read_bytes() == b"captured"
