"""rigkit.core.safefs: inputs refused before they are opened when they are no regular
file, reads bounded, rigkit's own folders opened once and worked in by descriptor."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

from rigkit.core.safefs import (
    open_folder,
    open_input,
    read_input,
    read_regular,
    remove_files,
)
from rigkit.errors import InputError


def test_a_fifo_or_a_device_is_refused_without_blocking(tmp_path: Path) -> None:
    os.mkfifo(tmp_path / "fifo.png")
    (tmp_path / "link.png").symlink_to(tmp_path / "fifo.png")
    for path, what in [(tmp_path / "fifo.png", "is a FIFO"), (tmp_path / "link.png", "is a FIFO"),
                       (Path("/dev/zero"), "is a device"), (tmp_path, "is a folder"),
                       (tmp_path / "gone.png", "no such file")]:
        with pytest.raises(InputError, match=what):
            open_input(path)


def test_reads_stop_at_their_limit_before_reading(tmp_path: Path) -> None:
    big = tmp_path / "big.csv"
    with big.open("wb") as handle:
        handle.truncate(3 << 30)  # sparse
    with pytest.raises(InputError, match=r"big.csv: 3 GB, more than the 64 MB a log can be"):
        read_input(big, 64 << 20, "a log")
    with pytest.raises(InputError, match=r"big.csv: 3 GB, more than the 1 KB a note can be"):
        read_regular(big, 1024, "a note")
    (tmp_path / "small").write_bytes(b"12345")
    assert read_regular(tmp_path / "small", 5) == b"12345"
    with pytest.raises(InputError, match="5 bytes, more than the 4 bytes"):
        read_regular(tmp_path / "small", 4)


def test_a_folder_is_worked_in_by_its_descriptor(tmp_path: Path) -> None:
    folder, elsewhere = tmp_path / "staging", tmp_path / "elsewhere"
    folder.mkdir()
    elsewhere.mkdir()
    for name in ("a", "b"):
        (folder / name).write_text("staged")
        (elsewhere / name).write_text("someone's")
    (folder / "link").symlink_to(elsewhere / "a")
    fd = open_folder(folder)
    try:
        folder.rename(tmp_path / "moved")  # swapped for a link to elsewhere meanwhile
        folder.symlink_to(elsewhere, target_is_directory=True)
        remove_files(fd, lambda name: True)
    finally:
        os.close(fd)
    assert sorted(p.name for p in (tmp_path / "moved").iterdir()) == ["link"]  # links kept
    assert sorted(p.name for p in elsewhere.iterdir()) == ["a", "b"]
    with pytest.raises(InputError, match="staging: is a symbolic link, not a folder"):
        open_folder(folder)
