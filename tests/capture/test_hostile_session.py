"""A session folder treated as untrusted (issue 36; docs/sessions.md, "A session folder
from someone else"): links where rigkit writes, locks or deletes, FIFOs where it reads,
names that would leave the folder. Each refusal is one line naming the path, exit
status 2, and nothing outside the session, nor any original frame, changes."""

from __future__ import annotations

import os
import threading
from collections.abc import Callable
from pathlib import Path

import pytest
import yaml

from rigkit.cli import main
from tests.conftest import copy_session

ADD_TARGET = ["--name", "X", "--pixel", "10", "10", "--range-m", "300"]


def _within(seconds: float, run: Callable[[], int]) -> int:
    """``run()``'s result, failing the test if it has not returned within ``seconds``
    (a command blocked for ever on a FIFO)."""
    result: list[int] = []
    worker = threading.Thread(target=lambda: result.append(run()), daemon=True)
    worker.start()
    worker.join(seconds)
    assert result, f"still running after {seconds} s (blocked on a FIFO?)"
    return result[0]


@pytest.fixture
def session(small_session: Path, tmp_path: Path) -> Path:
    return copy_session(small_session, tmp_path)


@pytest.fixture
def outside(tmp_path: Path) -> Path:
    """A file outside the session that must never change."""
    path = tmp_path / "precious.txt"
    path.write_text("do not touch\n")
    return path


def _originals(session: Path) -> dict[str, bytes]:
    return {p.name: p.read_bytes() for p in (session / "raw").iterdir()}


@pytest.mark.parametrize("target", ["frame", "outside"])
def test_a_lock_that_is_a_link_is_refused_and_its_target_kept(
    session: Path, outside: Path, target: str, capsys: pytest.CaptureFixture[str]
) -> None:
    before = _originals(session)
    (session / ".lock").unlink(missing_ok=True)
    (session / ".lock").symlink_to(session / "raw" / "left.png" if target == "frame"
                                   else outside)
    assert main(["session", "add-target", str(session), *ADD_TARGET]) == 2
    err = capsys.readouterr().err
    assert f"{session / '.lock'}: is a symbolic link" in err and err.count("\n") == 1
    assert _originals(session) == before and outside.read_text() == "do not touch\n"


def test_a_staging_folder_that_is_a_link_deletes_nothing(
    session: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    before = _originals(session)
    if (session / ".staging").is_dir():
        (session / ".staging").rmdir()
    (session / ".staging").symlink_to(session / "raw", target_is_directory=True)
    for command in (["session", "show", str(session)],  # shown as it is, with a warning
                    ["session", "add-target", str(session), *ADD_TARGET],
                    ["process", str(session)]):
        assert main(command) == {"show": 0, "add-target": 2, str(session): 1}[command[1]]
        captured = capsys.readouterr()
        assert f"{session / '.staging'}: is a symbolic link, not a folder" in (
            captured.out + captured.err)
    assert _originals(session) == before


@pytest.mark.parametrize("name", ["history.log", "comparisons.csv"])
def test_logs_that_are_links_are_not_appended_through(
    session: Path, outside: Path, name: str, capsys: pytest.CaptureFixture[str]
) -> None:
    (session / name).unlink(missing_ok=True)
    (session / name).symlink_to(outside)
    command = ["process", str(session)] if name == "comparisons.csv" else [
        "session", "add-target", str(session), *ADD_TARGET]
    assert main(command) != 0
    captured = capsys.readouterr()
    assert f"{session / name}: is a symbolic link" in captured.out + captured.err
    assert outside.read_text() == "do not touch\n"


def test_a_raw_folder_that_is_a_link_stores_nothing_outside(
    session: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    elsewhere = tmp_path / "elsewhere"
    (session / "raw").rename(elsewhere)
    (session / "raw").symlink_to(elsewhere, target_is_directory=True)
    before = sorted(p.name for p in elsewhere.iterdir())
    frame = tmp_path / "new.png"
    frame.write_bytes((elsewhere / "left.png").read_bytes())
    assert main(["session", "add-frame", str(session), "--position", "left", "--burst",
                 str(frame)]) == 2
    assert f"{session / 'raw'}: is a symbolic link, not a folder" in capsys.readouterr().err
    assert sorted(p.name for p in elsewhere.iterdir()) == before


@pytest.mark.parametrize("name", ["../escaped", "/tmp/escaped", "a/b"])
def test_a_session_name_that_is_a_path_is_refused_on_load(
    session: Path, tmp_path: Path, name: str, capsys: pytest.CaptureFixture[str]
) -> None:
    data = yaml.safe_load((session / "session.yaml").read_text())
    data["name"] = name
    (session / "session.yaml").write_text(yaml.safe_dump(data))
    out = tmp_path / "export"
    assert main(["export", str(session), "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert "session.yaml: name: not a usable name" in err and name in err
    assert not (tmp_path / "escaped.las").exists() and not Path("/tmp/escaped.las").exists()


def test_a_session_file_that_is_a_link_is_not_read(
    session: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    secret = tmp_path / "secret.txt"
    secret.write_text("root:$6$very-secret-hash:19000:0:99999:7:::\n")
    (session / "session.yaml").unlink()
    (session / "session.yaml").symlink_to(secret)
    assert main(["session", "show", str(session)]) == 2
    err = capsys.readouterr().err
    assert "session.yaml: is a symbolic link" in err and "very-secret" not in err


@pytest.mark.parametrize(("name", "reader"), [(".lock", "add-target"),
                                              ("history.log", "add-target"),
                                              ("comparisons.csv", "report")])
def test_a_fifo_never_hangs_a_command(
    session: Path, name: str, reader: str, capsys: pytest.CaptureFixture[str]
) -> None:
    (session / name).unlink(missing_ok=True)
    os.mkfifo(session / name)
    commands = {"show": ["session", "show", str(session)],
                "add-target": ["session", "add-target", str(session), *ADD_TARGET],
                "report": ["report", str(session), "--out", str(session.parent / "report")]}
    for what, command in commands.items():
        code = _within(10, lambda command=command: main(command))
        err = capsys.readouterr().err
        if what == reader:  # the command that opens it names it
            assert code == 2 and f"{session / name}: is a FIFO" in err, err
            assert "(None)" not in err
    assert (session / name).is_fifo()


def test_a_log_that_is_a_device_is_named(session: Path, capsys: pytest.CaptureFixture[str]
                                         ) -> None:
    (session / "history.log").unlink(missing_ok=True)
    (session / "history.log").symlink_to("/dev/zero")
    assert main(["session", "add-target", str(session), *ADD_TARGET]) == 2
    err = capsys.readouterr().err
    assert f"{session / 'history.log'}:" in err and "Invalid argument" not in err


def _edit(session: Path, change: Callable[[dict], None]) -> None:
    data = yaml.safe_load((session / "session.yaml").read_text())
    change(data)
    (session / "session.yaml").write_text(yaml.safe_dump(data))


def test_a_reading_no_rangefinder_gives_is_refused_on_load(
    session: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    _edit(session, lambda d: d["targets"][0]["readings"][0].update(slope_distance_m=3e-304))
    assert main(["process", str(session)]) == 1
    out = capsys.readouterr().out
    assert "targets[0].readings[0].slope_distance_m: must be a range the rangefinder gives" in out


def test_one_bad_session_does_not_stop_the_others(
    session: Path, small_session: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    bad = copy_session(small_session, tmp_path, "bad")

    def huge(data: dict) -> None:
        left = data["frames"]["left"]
        (left[0] if isinstance(left, list) else left)["size_px"] = [1e308, 1e308]

    _edit(bad, huge)
    assert main(["process", str(session), str(bad), "--jobs", "1"]) == 1
    out = capsys.readouterr().out
    assert "1 processed, 1 failed" in out and "size_px" in out
    assert (session / "results" / "depth.npy").is_file()


def test_a_huge_file_is_refused_before_it_is_copied(
    session: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    import time

    sparse = tmp_path / "huge.png"
    with sparse.open("wb") as handle:
        handle.write((session / "raw" / "left.png").read_bytes()[:64])
        handle.truncate(4 << 30)  # 4 GB, sparse: nothing to copy but its size
    t0 = time.monotonic()
    assert main(["session", "add-frame", str(session), "--position", "left", "--burst",
                 str(sparse)]) == 2
    assert time.monotonic() - t0 < 5
    assert "4.0 GB, larger than any frame rigkit takes" in capsys.readouterr().err
    assert not list((session / ".staging").glob("*"))


def test_a_file_name_that_is_not_utf8_is_stored_and_logged(
    session: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    odd = Path(os.fsdecode(bytes(tmp_path) + b"/left-\xff.png"))
    odd.write_bytes((session / "raw" / "left.png").read_bytes())
    assert main(["session", "add-frame", str(session), "--position", "left", "--replace",
                 str(odd)]) == 0
    assert (session / "raw" / "left-_.png").read_bytes() == odd.read_bytes()
    assert "left raw/left-_.png" in (session / "history.log").read_text()
    assert "left-_.png" in (session / "session.yaml").read_text()


def test_a_session_whose_path_is_not_utf8_is_processed(
    small_session: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    folder = Path(os.fsdecode(bytes(tmp_path) + b"/card-\xff"))
    folder.mkdir()
    session = copy_session(small_session, folder)
    assert main(["process", str(session), "--quiet"]) == 0  # once a SIGSEGV in OpenCV
    assert (session / "results" / "depth.npy").is_file()


def test_a_log_that_is_a_link_fails_its_session_before_the_work(
    processed_small: Path, small_session: Path, tmp_path: Path, outside: Path,
    capsys: pytest.CaptureFixture[str],
) -> None:
    """Said before the run, not after it replaced the results; the next session is
    processed all the same."""
    bad = copy_session(processed_small, tmp_path, "bad")
    results = {p.name: p.read_bytes() for p in (bad / "results").iterdir()}
    (bad / "history.log").unlink()
    (bad / "history.log").symlink_to(outside)
    good = copy_session(small_session, tmp_path, "good")
    assert main(["process", str(bad), str(good), "--jobs", "1"]) == 1
    out = capsys.readouterr().out
    assert "1 processed, 1 failed" in out and "history.log: is a symbolic link" in out
    assert {p.name: p.read_bytes() for p in (bad / "results").iterdir()} == results
    assert (good / "results" / "depth.npy").is_file()
    assert outside.read_text() == "do not touch\n"


@pytest.mark.parametrize("name", ["depth.npy", "depth.json"])
def test_results_that_are_links_are_not_exported(
    processed_small: Path, tmp_path: Path, name: str, capsys: pytest.CaptureFixture[str]
) -> None:
    session = copy_session(processed_small, tmp_path)
    elsewhere = tmp_path / f"elsewhere-{name}"
    (session / "results" / name).rename(elsewhere)
    (session / "results" / name).symlink_to(elsewhere)
    assert main(["export", str(session), "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err
    assert f"results/{name}: is a symbolic link" in err and len(err.strip().splitlines()) == 1
    assert not list((tmp_path / "out").glob("*.ply")) if (tmp_path / "out").exists() else True


def test_a_frame_name_with_a_control_character_is_refused(
    session: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    def nul(data: dict) -> None:
        left = data["frames"]["left"]
        (left[0] if isinstance(left, list) else left)["file"] = "raw/left.png\0.txt"

    _edit(session, nul)
    assert main(["session", "show", str(session)]) == 2
    err = capsys.readouterr().err
    assert "must be a file name without control characters" in err and "Traceback" not in err


def test_escape_sequences_in_a_note_are_shown_not_obeyed(
    session: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    _edit(session, lambda data: data.update(notes="clear\x1b[2J\x1b[Hdone",
                                            operator="\x1b]0;x\x07"))
    assert main(["session", "show", str(session)]) == 0
    out = capsys.readouterr().out
    assert "\x1b" not in out and "\x07" not in out and "clear\\x1b[2J\\x1b[Hdone" in out
