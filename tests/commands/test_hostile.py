"""The command line under an unlucky user: read-only sessions and full disks, a lost
rangefinder, a killed parent, the wrong protocol, library chatter. Each test is a row of
issue 25's table (the session-level rows are in tests/capture/test_robustness.py)."""

from __future__ import annotations

import errno
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from rigkit.capture import create_session, load_session
from rigkit.cli import main
from rigkit.core import files
from tests.conftest import copy_session, rig_file


def _failing(error: int):
    def write(*args, **kwargs):
        raise OSError(error, os.strerror(error), str(args[0]) if args else None)

    return write


@pytest.mark.parametrize("error, hint", [(errno.EROFS, "read-only"), (errno.ENOSPC, "full"),
                                         (errno.EACCES, "permission denied")])
def test_an_unwritable_session_is_one_line_for_add_target(tmp_path: Path, capsys, monkeypatch,
                                                          error: int, hint: str) -> None:
    session = create_session(tmp_path / "s", rig_file(tmp_path, (64, 48)))
    monkeypatch.setattr(files, "write_with", _failing(error))
    code = main(["session", "add-target", str(session.path), "--pixel", "10", "10",
                 "--range-m", "300"])
    err = capsys.readouterr().err.strip()
    assert code == 2 and len(err.splitlines()) == 1 and hint in err
    assert "please report" not in err and "Traceback" not in err
    assert load_session(session.path).targets == ()


def test_a_full_disk_while_processing_is_no_internal_error(small_session: Path, tmp_path: Path,
                                                          capsys, monkeypatch) -> None:
    copy = copy_session(small_session, tmp_path)
    monkeypatch.setattr("rigkit.batch.session.replace_folder", _failing(errno.ENOSPC))
    assert main(["process", str(copy)]) == 1
    out = capsys.readouterr()
    assert "No space left on device (the disk is full" in out.out + out.err
    assert "please report" not in out.out + out.err
    assert not (copy / "results").exists()


def test_depth_to_an_unwritable_place_fails_before_the_work(
        scene_dir: Path, tmp_path: Path, capsys, monkeypatch: pytest.MonkeyPatch) -> None:
    # Before the pipeline, not after it: told by the run never starting. (A bound of 1 s
    # on the whole call, the runner's imports included, failed on a busy machine.)
    def never(*args: object, **kwargs: object) -> None:
        raise AssertionError("the depth run started before --out was checked")

    monkeypatch.setattr("rigkit.commands.depth_run.run_depth", never)
    blocker = tmp_path / "file"
    blocker.write_text("")
    frames = [str(scene_dir / f"{v}.png") for v in ("left", "right", "back")]
    assert main(["depth", *frames, "--out", str(blocker / "d.npy"), "--focal-px", "9159",
                 "--baseline-lr", "2", "--baseline-lb", "2", "--quiet"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "is a file, not a folder" in err


def test_readings_received_before_the_device_is_lost_are_kept(tmp_path: Path, capsys) -> None:
    # Before: the device lost at shot 3 of --shots 3 threw the two readings away.
    session = create_session(tmp_path / "s", rig_file(tmp_path, (64, 48)))
    code = main(["session", "add-target", str(session.path), "--pixel", "10", "10",
                 "--device", "sim://trupulse?interval=0.05&disconnect_after=2", "--shots", "3",
                 "--timeout", "5"])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1
    assert "stopped at reading 3 of 3" in err[0] and "the 2 received are kept" in err[0]
    assert len(load_session(session.path).target("T1").readings) == 2


def test_a_simulator_is_read_with_its_own_protocol(tmp_path: Path, capsys) -> None:
    # Before: `rangefinder log --port sim://vectronix` without --protocol waited for ever.
    out = tmp_path / "log.jsonl"
    assert main(["rangefinder", "log", "--port", "sim://vectronix", "--output", str(out),
                 "--count", "1"]) == 0
    assert len(out.read_text().splitlines()) == 1


def _children(pid: int) -> list[int]:
    found = []
    for entry in Path("/proc").iterdir():
        if entry.name.isdigit():
            try:
                stat = (entry / "stat").read_text()
            except OSError:
                continue
            if int(stat.rsplit(")", 1)[1].split()[1]) == pid:
                found.append(int(entry.name))
    return found


@pytest.mark.skipif(not Path("/proc").is_dir(), reason="needs /proc to find the workers")
def test_workers_end_when_their_parent_is_killed(small_session: Path, tmp_path: Path) -> None:
    # Before: after `kill -9` of `rigkit process --jobs 2` the workers finished and then
    # waited for ever on the progress queue, holding 176 MB each.
    sessions = [copy_session(small_session, tmp_path, name=f"s{k}") for k in range(2)]
    parent = subprocess.Popen([sys.executable, "-m", "rigkit.cli", "process", "--jobs", "2",
                               *map(str, sessions)], stdout=subprocess.DEVNULL,
                              stderr=subprocess.DEVNULL)
    deadline = time.monotonic() + 60
    workers: list[int] = []
    while len(workers) < 2 and time.monotonic() < deadline:
        workers = [p for p in _children(parent.pid)
                   if "spawn" in Path(f"/proc/{p}/cmdline").read_text(errors="replace")
                   and "resource_tracker" not in Path(f"/proc/{p}/cmdline").read_text(
                       errors="replace")]
        time.sleep(0.1)
    assert workers, "the pool's workers never started"
    os.kill(parent.pid, signal.SIGKILL)
    parent.wait()
    deadline = time.monotonic() + 15
    while time.monotonic() < deadline and any(Path(f"/proc/{p}").exists() and
                                              "Z" not in _state(p) for p in workers):
        time.sleep(0.2)
    assert not [p for p in workers if Path(f"/proc/{p}").exists() and "Z" not in _state(p)]


def _state(pid: int) -> str:
    try:
        return Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except OSError:
        return "Z"


def test_a_decoder_complaint_is_not_printed(tmp_path: Path, scene_dir: Path, capfd) -> None:
    # Before: libpng's "libpng error: Read Error" reached the user before rigkit's line.
    data = (scene_dir / "left.png").read_bytes()
    (tmp_path / "left.png").write_bytes(data[: len(data) // 2])
    frames = [str(tmp_path / "left.png"), str(scene_dir / "right.png"),
              str(scene_dir / "back.png")]
    assert main(["depth", *frames, "--out", str(tmp_path / "d.npy"), "--focal-px", "9159",
                 "--baseline-lr", "2", "--baseline-lb", "2", "--quiet"]) == 2
    err = capfd.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("rigkit depth: error:") and "left.png" in err[0]
