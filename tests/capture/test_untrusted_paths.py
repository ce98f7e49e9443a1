"""Paths inside a session are not looked up again between check and use (issue 46;
docs/sessions.md, "A session folder from someone else"): the staging folder is emptied
through its descriptor, so swapping it for a link mid-cleanup deletes nothing elsewhere;
``derived/`` is one of the session's own folders, never followed when it is a link; a
cache file is read only up to what its frame can take; a FIFO named as a frame is
refused before it is opened; a frame's name that holds control characters is stored
under a safe name, and the session stays usable."""

from __future__ import annotations

import hashlib
import os
import shutil
import subprocess
import sys
import threading
import time
import tracemalloc
from collections.abc import Callable
from pathlib import Path

import cv2
import numpy as np
import pytest
import yaml

from rigkit.capture import load_session
from rigkit.capture.actions import clean_staging
from rigkit.cli import main
from rigkit.errors import InputError
from rigkit.imagefile.rawio import load_linear_grey
from tests.conftest import copy_session
from tests.dngutil import write_dng

H, W = 48, 64


def _ramp_dng(path: Path) -> Path:
    row = np.linspace(100, 3000, W)
    return write_dng(path, np.rint(np.tile(row, (H, 1))).astype(np.uint16))


def _sha256(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def _within(seconds: float, run: Callable[[], int]) -> int:
    """``run()``'s result, failing the test if it has not returned within ``seconds``
    (blocked on a FIFO)."""
    result: list[int] = []
    worker = threading.Thread(target=lambda: result.append(run()), daemon=True)
    worker.start()
    worker.join(seconds)
    assert result, f"still running after {seconds} s (blocked on a FIFO?)"
    return result[0]


_SWAP = """
import os, sys, time
staging, real, victim = sys.argv[1:4]
while True:
    try:
        os.rename(staging, real)
        os.symlink(victim, staging, target_is_directory=True)
        time.sleep(0.0002)
        os.unlink(staging)
        os.rename(real, staging)
        time.sleep(0.0002)
    except OSError:
        pass
"""
"""Swaps the staging folder for a link to the victim and back, for ever (a process of
its own: truly at the same time as the cleanup, with no import to wait for)."""


def test_a_staging_folder_swapped_for_a_link_mid_cleanup_deletes_nothing_elsewhere(
    tmp_path: Path,
) -> None:
    """Another process swaps ``.staging`` for a link to a folder of someone's files and
    back, as fast as it can, while the cleanup runs again and again (a swap between the
    cleanup's check and its deletes removed the linked folder's files)."""
    session = tmp_path / "s"
    staging, real = session / ".staging", session / ".staging-real"
    victim = tmp_path / "victim"
    victim.mkdir()
    names = [f"frame-{i}.png" for i in range(20)]
    staging.mkdir(parents=True)
    swapper = subprocess.Popen([sys.executable, "-c", _SWAP, str(staging), str(real),
                                str(victim)])
    try:
        while not staging.is_symlink():  # swapping has begun
            time.sleep(0.001)
        for name in names:  # what a swap in time would delete
            (victim / name).write_bytes(b"someone's frame")
        deadline = time.monotonic() + 3.0
        while time.monotonic() < deadline:
            try:
                clean_staging(session)
            except (InputError, OSError):  # a link at that moment: refused, nothing removed
                pass
            kept = {p.name for p in victim.iterdir()}
            assert kept >= set(names), f"deleted: {sorted(set(names) - kept)}"
    finally:
        swapper.kill()
        swapper.wait()


def test_a_derived_folder_that_is_a_link_is_never_written_through(tmp_path: Path) -> None:
    """The RAW cache of a session whose ``derived/`` links to a folder elsewhere is
    neither read from nor written into that folder: one line naming ``derived``."""
    frame = _ramp_dng(tmp_path / "left.dng")
    session = tmp_path / "s"
    session.mkdir()
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    (session / "derived").symlink_to(elsewhere, target_is_directory=True)
    with pytest.raises(InputError, match="derived: is a symbolic link"):
        load_linear_grey(frame, session / "derived", _sha256(frame))
    assert list(elsewhere.iterdir()) == []


def test_process_of_a_session_whose_derived_is_a_link_fails_it_alone(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    session = tmp_path / "s"
    rig = tmp_path / "rig.yaml"
    rig.write_text(yaml.safe_dump({
        "version": 1, "name": "tiny", "camera": {
            "model": "test", "resolution": [W, H],
            "focal_length": {"px": 2000.0, "tolerance_fraction": 0.0}},
        "baselines": {"C_lr": {"value_m": 2.0, "tolerance_m": 0.0},
                      "C_lb": {"value_m": 2.0, "tolerance_m": 0.0}}}))
    assert main(["session", "new", str(session), "--rig", str(rig)]) == 0
    for i, view in enumerate(("left", "right", "back")):
        frame = write_dng(tmp_path / f"{view}.dng", np.rint(np.tile(
            np.linspace(100, 2000 + 300 * i, W), (H, 1))).astype(np.uint16))
        assert main(["session", "add-frame", str(session), "--position", view,
                     str(frame)]) == 0
    shutil.rmtree(session / "derived")
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    (session / "derived").symlink_to(elsewhere, target_is_directory=True)
    capsys.readouterr()
    assert main(["process", str(session), "--quiet"]) == 1
    captured = capsys.readouterr()
    assert "derived: is a symbolic link" in captured.out + captured.err
    assert list(elsewhere.iterdir()) == []


def test_an_oversized_cache_file_is_not_read(tmp_path: Path) -> None:
    """A 600 MB file where a 64x48 frame's cache should be (a few KB) is not read: the
    frame is decoded again and the cache replaced."""
    frame = _ramp_dng(tmp_path / "left.dng")
    sha, cache = _sha256(frame), tmp_path / "derived"
    cache.mkdir()
    huge = cache / f"{sha[:16]}.linear.png"
    with huge.open("wb") as handle:
        handle.truncate(600 << 20)  # sparse: no disk used
    tracemalloc.start()
    try:
        grey = load_linear_grey(frame, cache, sha, (W, H))
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert peak < 50 << 20, f"{peak / 2**20:.0f} MB allocated: the cache file was read"
    assert grey.shape == (H, W)
    replaced = cv2.imread(str(huge), cv2.IMREAD_UNCHANGED)
    assert replaced is not None and replaced.shape == (H, W) and huge.stat().st_size < 1 << 20


def test_a_cache_file_that_is_a_fifo_or_a_link_is_no_cache(tmp_path: Path) -> None:
    frame = _ramp_dng(tmp_path / "left.dng")
    sha, cache = _sha256(frame), tmp_path / "derived"
    cache.mkdir()
    outside = tmp_path / "outside.png"
    outside.write_bytes(b"keep")
    name = f"{sha[:16]}.linear.png"
    (cache / name).symlink_to(outside)
    load_linear_grey(frame, cache, sha, (W, H))
    assert outside.read_bytes() == b"keep" and not (cache / name).is_symlink()
    (cache / name).unlink()
    os.mkfifo(cache / name)
    grey = load_linear_grey(frame, cache, sha, (W, H))  # would block if opened to read
    assert grey.shape == (H, W) and (cache / name).is_file()


@pytest.mark.parametrize("name", ["ff.png", "ff.nef"])
def test_a_fifo_as_a_frame_is_refused_before_it_is_opened(
    scene_dir: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str], name: str
) -> None:
    """rigkit depth with a rig profile (whose EXIF check read the frames first) and rig
    check --capture blocked for ever on a FIFO."""
    fifo = tmp_path / name
    os.mkfifo(fifo)
    rig = tmp_path / "rig.yaml"
    rig.write_text(yaml.safe_dump({
        "version": 1, "name": "scene", "camera": {
            "model": "test", "resolution": [960, 720],
            "focal_length": {"px": 9159.0, "tolerance_fraction": 0.0}},
        "baselines": {"C_lr": {"value_m": 2.0, "tolerance_m": 0.0},
                      "C_lb": {"value_m": 2.0, "tolerance_m": 0.0}}}))
    others = [str(scene_dir / "right.png"), str(scene_dir / "back.png")]
    for argv in (["depth", str(fifo), *others, "--rig", str(rig), "--out",
                  str(tmp_path / "d.npy"), "--quiet"],
                 ["rig", "check", str(rig), "--capture", str(fifo), *others]):
        assert _within(10, lambda argv=argv: main(argv)) == 2
        err = capsys.readouterr().err.strip()
        assert err.endswith(f"{fifo}: is a FIFO, not a file") and len(err.splitlines()) == 1


@pytest.mark.parametrize("name", ["a\nb.png", "left\x1b[2J\x1b]0;owned\x07.png",
                                  "r\u202egnp.png"])
def test_a_frame_named_with_control_characters_is_stored_under_a_safe_name(
    small_session: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str], name: str
) -> None:
    """Before: add-frame of such a file exited 0, and then every command refused
    session.yaml (the session was bricked); its newline forged a line of history.log."""
    session = copy_session(small_session, tmp_path)
    frame = tmp_path / name
    shutil.copy(session / "raw" / "left.png", frame)
    history = (session / "history.log").read_text().splitlines()
    assert main(["session", "add-frame", str(session), "--position", "left", str(frame),
                 "--replace"]) == 0
    out = capsys.readouterr().out
    assert "note: " in out and "stored as raw/" in out and "\x1b" not in out
    stored = load_session(session).frames["left"]
    assert stored.file.isprintable() and Path(stored.file).name != name
    assert stored.source.isprintable() and str(tmp_path) in stored.source
    assert len((session / "history.log").read_text().splitlines()) == len(history) + 1
    assert main(["session", "show", str(session)]) == 0  # every command loads it
