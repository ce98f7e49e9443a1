"""Frames arriving in a watched folder: counted once complete, never twice."""

from __future__ import annotations

import threading
import time
from pathlib import Path

from rigkit.tui.watch import arrivals, is_frame_file


def test_frame_files_are_images_and_not_hidden() -> None:
    assert is_frame_file(Path("DSCN0101.NRW")) and is_frame_file(Path("a.PNG"))
    assert not is_frame_file(Path(".DSCN0101.NRW.part")) and not is_frame_file(Path("a.txt"))


def test_a_file_counts_once_its_size_stops_changing(tmp_path: Path) -> None:
    (tmp_path / "old.png").write_bytes(b"there before")
    stop = threading.Event()
    finished: dict[str, float] = {}

    def camera() -> None:
        time.sleep(0.3)
        (tmp_path / "notes.txt").write_text("not a frame")
        with (tmp_path / "DSCN0101.PNG").open("wb") as handle:
            for _ in range(4):  # written in pieces, 0.15 s apart
                handle.write(b"x" * 1000)
                handle.flush()
                finished["at"] = time.monotonic()
                time.sleep(0.15)
        time.sleep(0.8)
        stop.set()

    threading.Thread(target=camera, daemon=True).start()
    seen = [(path.name, path.stat().st_size, time.monotonic())
            for path in arrivals(tmp_path, stop, settle_s=0.3)]
    assert [(name, size) for name, size, _ in seen] == [("DSCN0101.PNG", 4000)]
    assert seen[0][2] >= finished["at"] + 0.3  # not before it stopped growing for 0.3 s


def test_watching_ends_when_the_folder_goes(tmp_path: Path) -> None:
    card = tmp_path / "card"
    card.mkdir()
    stop = threading.Event()
    threading.Timer(0.3, card.rmdir).start()
    threading.Timer(5.0, stop.set).start()  # only if it did not end by itself
    start = time.monotonic()
    assert list(arrivals(card, stop, settle_s=0.2)) == []
    assert time.monotonic() - start < 3.0
    stop.set()
