"""The one rule for outputs (rigkit.core.outputs): where an output may not go, how rigkit
knows a file is its own (the ledger: inode, size and time as written), and a file that
appears at an output's name while the output is written is not replaced."""

from __future__ import annotations

import json
import os
import shutil
from pathlib import Path

import pytest

from rigkit.core.outputs import (
    LEDGER,
    OutputLog,
    check_output_file,
    check_output_folder,
    check_output_log,
    record_outputs,
    session_part,
    staged_outputs,
    write_outputs,
)
from rigkit.errors import InputError


def _session(folder: Path) -> Path:
    (folder / "raw").mkdir(parents=True)
    (folder / "session.yaml").write_text("format: rigkit-session/1\n")
    return folder


def test_a_sessions_own_parts_are_found_through_links_and_dot_dot(tmp_path: Path) -> None:
    session = _session(tmp_path / "s")
    (tmp_path / "to-raw").symlink_to(session / "raw", target_is_directory=True)
    (session / "export").mkdir()
    for path, part in [(session / "raw" / "x.npy", "raw"), (session / "session.yaml", None),
                       (tmp_path / "to-raw" / "x.npy", "raw"),
                       (session / "export" / ".." / "raw" / "a" / "b.tif", "raw"),
                       (session / ".staging" / "x", ".staging"),
                       (session / "comparisons.csv", "comparisons.csv")]:
        found = session_part(path)
        assert found is not None and found[0] == session, path
        assert found[1][0] == (part or "session.yaml")
    assert session_part(session / "export" / "x.ply") is None
    assert session_part(tmp_path / "x.npy") is None


def test_a_file_is_rigkits_while_its_inode_size_and_time_match(tmp_path: Path) -> None:
    write_outputs(tmp_path, {"a.txt": "one\n", "b.txt": "two\n"}, "--out", "report")
    ledger = json.loads((tmp_path / LEDGER).read_text())["files"]
    assert set(ledger) == {"a.txt", "b.txt"}
    check_output_file(tmp_path / "a.txt", "--out")  # its own: may be written again
    write_outputs(tmp_path, {"a.txt": "one again\n"}, "--out", "report")
    with (tmp_path / "b.txt").open("a") as edited:
        edited.write("edited by hand\n")
    shutil.copy(tmp_path / "a.txt", tmp_path / "copy.txt")
    os.replace(tmp_path / "copy.txt", tmp_path / "a.txt")  # same bytes, another file
    for name in ("a.txt", "b.txt"):
        with pytest.raises(InputError, match=f"{name} exists and was not written by rigkit"):
            check_output_file(tmp_path / name, "--out")


def test_a_command_replaces_only_its_own_products_and_appends_only_to_logs(
    tmp_path: Path,
) -> None:
    """Before: any file in a folder's ledger could be written over by any command, and
    appended to as a log: a scene's ground truth by ``depth --out``, a scene's frame by
    a depth preview, a frame by ``--raw-log``."""
    write_outputs(tmp_path, {"left.png": b"frame", "report.txt": "r\n"}, "--out", "synth")
    check_output_file(tmp_path / "left.png", "OUT_DIR", "synth")  # a scene again
    check_output_file(tmp_path / "left.png", "--out")  # the command line's first look
    for product in ("depth", "report", "export", "profile", "eval", "experiments"):
        with pytest.raises(InputError, match="left.png is part of a scene that rigkit "
                                             "synth rendered .* not this command's"):
            check_output_file(tmp_path / "left.png", "--out", product)
    for opened in (lambda: OutputLog(tmp_path / "left.png", "--raw-log", "raw-log"),
                   lambda: check_output_log(tmp_path / "left.png", "--raw-log")):
        with pytest.raises(InputError, match="left.png is part of a scene .*, not this "
                                             "option's log: rigkit appends only to a log"):
            opened()
    assert (tmp_path / "left.png").read_bytes() == b"frame"
    serial = tmp_path / "serial.log"
    with OutputLog(serial, "--raw-log", "raw-log") as log:
        log.write("$PLTIT,HV,300.0,M*00\n")
    with pytest.raises(InputError, match="serial.log is a log of serial traffic"):
        check_output_file(serial, "--out")
    with pytest.raises(InputError, match="serial.log is a log of serial traffic .* not this "
                                         "option's log"):  # readings into a raw log: never
        OutputLog(serial, "--output", "readings")
    with OutputLog(serial, "--raw-log", "raw-log") as log:  # a log goes on growing
        log.write("$PLTIT,HV,301.0,M*00\n")
    assert serial.read_text().count("PLTIT") == 2


def test_commands_ending_at_once_into_one_folder_keep_every_entry(tmp_path: Path) -> None:
    """Before: the ledger was read, changed and written back unlocked, and 16 runs of
    rigkit depth side by side into one folder kept 70 of their 80 entries (their files
    then refused to the next run)."""
    from concurrent.futures import ProcessPoolExecutor

    names = [[f"p{p}-{n}.txt" for n in range(40)] for p in range(4)]
    for name in (n for batch in names for n in batch):
        (tmp_path / name).write_text("x\n")
    with ProcessPoolExecutor(4) as pool:
        list(pool.map(_record_each, [tmp_path] * 4, names))
    ledger = json.loads((tmp_path / LEDGER).read_text())["files"]
    assert len(ledger) == 160


def _record_each(folder: Path, names: list[str]) -> None:
    for name in names:
        record_outputs(folder, [name], "report")


def test_a_damaged_or_linked_ledger_claims_nothing(tmp_path: Path) -> None:
    write_outputs(tmp_path, {"a.txt": "one\n"}, "--out", "report")
    (tmp_path / LEDGER).write_text("{not json")
    with pytest.raises(InputError, match="not written by rigkit"):
        check_output_file(tmp_path / "a.txt", "--out")
    other = tmp_path / "other"
    other.mkdir()
    write_outputs(other, {"a.txt": "one\n"}, "--out", "report")
    (tmp_path / LEDGER).unlink()
    (tmp_path / LEDGER).symlink_to(other / LEDGER)  # another folder's ledger, by a link
    with pytest.raises(InputError, match="not written by rigkit"):
        check_output_file(tmp_path / "a.txt", "--out")
    with pytest.raises(InputError, match="where rigkit records what it wrote"):
        check_output_file(tmp_path / LEDGER, "--out")


def test_a_file_that_appears_while_outputs_are_written_is_not_replaced(tmp_path: Path) -> None:
    with pytest.raises(InputError, match="late.txt exists and was not written by rigkit"):
        with staged_outputs(tmp_path, ["early.txt", "late.txt"], "--out", "report") as staging:
            (staging / "early.txt").write_text("rigkit's\n")
            (staging / "late.txt").write_text("rigkit's\n")
            (tmp_path / "late.txt").write_text("someone's\n")  # meanwhile
    assert sorted(p.name for p in tmp_path.iterdir()) == ["late.txt"]  # nothing staged left
    assert (tmp_path / "late.txt").read_text() == "someone's\n"


def test_links_fifos_devices_and_files_are_no_folders(tmp_path: Path) -> None:
    (tmp_path / "real").mkdir()
    (tmp_path / "link").symlink_to(tmp_path / "real", target_is_directory=True)
    os.mkfifo(tmp_path / "fifo")
    (tmp_path / "file").write_text("x")
    check_output_folder(tmp_path / "real", "--out")
    check_output_folder(tmp_path / "new" / "deeper", "--out")
    for name, what in [("link", "is a symbolic link"), ("fifo", "is a FIFO"),
                       ("file", "is a regular file, not a folder")]:
        with pytest.raises(InputError, match=what):
            check_output_folder(tmp_path / name, "--out")
    with pytest.raises(InputError, match="is a device"):
        check_output_folder(Path("/dev/null"), "--out")
    with pytest.raises(InputError, match="d.npy: .*file is a file, not a folder"):
        check_output_file(tmp_path / "file" / "d.npy", "--out")


def test_a_log_is_rigkits_while_it_grows_and_no_file_that_takes_its_place_is(
    tmp_path: Path,
) -> None:
    log = tmp_path / "laser.jsonl"
    with OutputLog(log, "--output", "readings") as output:
        output.write('{"slope_distance_m": 300.0}\n')
    with OutputLog(log, "--output", "readings") as output:  # its own, appended to since
        output.write('{"slope_distance_m": 301.0}\n')
    with log.open("a") as torn:  # a writer stopped mid-line: still the log it was
        torn.write('{"slope')
    with OutputLog(log, "--output", "readings") as output:
        output.write("\n")
    log.unlink()
    log.write_text("someone else's notes\n")  # a new file at its name (often its inode)
    with pytest.raises(InputError, match="is no log rigkit started"):
        OutputLog(log, "--output", "readings")
    assert log.read_text() == "someone else's notes\n"
