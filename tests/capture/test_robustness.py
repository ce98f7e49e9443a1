"""A session under a hostile or unlucky user: concurrent changes, bombs, full disks,
crashes half way, absurd values, links and paths that lead out of it. Each test is a row
of issue 25's table; docs/sessions.md ("What rigkit guarantees") names them."""

from __future__ import annotations

import errno
import multiprocessing
import os
import struct
import zlib
from pathlib import Path

import cv2
import numpy as np
import pytest

from rigkit.capture import (
    LaserReading,
    add_frame,
    add_target,
    create_session,
    frame_problems,
    load_session,
)
from rigkit.capture.actions import create_session_in
from rigkit.capture.comparisons import LOG_NAME, append_rows, read_rows
from rigkit.capture.lock import session_lock
from rigkit.capture.results import stale_results
from rigkit.cli import main
from rigkit.core import files
from rigkit.errors import InputError
from tests.conftest import copy_session, make_row, rig_file

SIZE = (64, 48)


def png(path: Path, seed: int = 0, size: tuple[int, int] = SIZE) -> Path:
    rng = np.random.default_rng(seed)
    noise = cv2.GaussianBlur(rng.random((size[1], size[0])), (0, 0), 2.0)
    cv2.imwrite(str(path), cv2.normalize(noise, None, 0, 255, cv2.NORM_MINMAX).astype(np.uint8))
    return path


def new_session(folder: Path, name: str = "s"):
    return create_session(folder / name, rig_file(folder, SIZE))


def reading(metres: float) -> LaserReading:
    return LaserReading(metres, "2026-11-24T10:00:00Z", "manual")


# --------------------------------------------------------------------------- 1: one at a time


def _add_readings(path: str, worker: int, count: int) -> None:
    for k in range(count):
        add_target(load_session(path), "mast", (10.0, 10.0),
                   readings=[reading(300.0 + worker + k / 100)])


def _add_burst_frame(path: str, frame: str) -> None:
    add_frame(load_session(path), "left", frame, burst=True)


def test_many_writers_at_once_keep_every_reading(tmp_path: Path) -> None:
    # Before: 20 additions logged, 15-19 readings kept.
    session = new_session(tmp_path)
    add_target(session, "mast", (10.0, 10.0), readings=[reading(299.0)])
    context = multiprocessing.get_context("fork")
    workers = [context.Process(target=_add_readings, args=(str(session.path), w, 4))
               for w in range(6)]
    for worker in workers:
        worker.start()
    for worker in workers:
        worker.join(60)
    assert all(worker.exitcode == 0 for worker in workers)
    assert len(load_session(session.path).target("mast").readings) == 1 + 6 * 4
    history = (session.path / "history.log").read_text().splitlines()
    assert sum("add-target" in line for line in history) == 1 + 6 * 4


def test_concurrent_frames_all_join_the_burst(tmp_path: Path) -> None:
    # Before: 3 concurrent add-frame kept 1-2 of 3 frames.
    session = new_session(tmp_path)
    add_frame(session, "left", png(tmp_path / "a.png"))
    frames = [str(png(tmp_path / f"b{k}.png", seed=k + 1)) for k in range(3)]
    context = multiprocessing.get_context("fork")
    workers = [context.Process(target=_add_burst_frame, args=(str(session.path), f))
               for f in frames]
    for worker in workers:
        worker.start()
    for worker in workers:
        worker.join(60)
    assert len(load_session(session.path).bursts["left"]) == 4


def test_a_change_while_processing_waits_then_names_who_holds_it(tmp_path: Path) -> None:
    session = new_session(tmp_path)
    with session_lock(session.path, "process"):
        with pytest.raises(InputError, match=r"busy: being processed by PID \d+ since"):
            from rigkit.capture import actions

            with actions.changing(session.path, "add-target", wait_s=0.2):
                pass


def test_session_show_says_results_are_stale(processed_small: Path, tmp_path: Path,
                                             capsys) -> None:
    copy = copy_session(processed_small, tmp_path)
    assert stale_results(load_session(copy)) is None
    session = load_session(copy)
    target = session.targets[0]
    add_target(session, target.name, target.pixel, window_px=target.window_px,
               readings=[reading(301.0)])
    assert main(["session", "show", str(copy)]) == 0
    assert "before the targets changed; process again" in capsys.readouterr().out


# --------------------------------------------------------------------------- 2, 18: bounded


def _bomb() -> str:
    text = 'a: &a ["lol","lol","lol","lol","lol","lol","lol","lol","lol"]\n'
    for new, old in zip("bcdefghi", "abcdefgh", strict=True):
        text += f"{new}: &{new} [*{old},*{old},*{old},*{old},*{old},*{old},*{old},*{old},*{old}]\n"
    return text


def test_an_alias_bomb_in_session_yaml_is_refused_at_once(tmp_path: Path) -> None:
    # Before: 33 s and 2.6 GB, then MemoryError.
    session = new_session(tmp_path)
    (session.path / "session.yaml").write_text(_bomb())
    with pytest.raises(InputError, match="aliases .* expand to over 1,000,000 values"):
        load_session(session.path)


@pytest.mark.parametrize("kind", ["device", "fifo", "huge"])
def test_a_rig_that_is_no_regular_file_of_bounded_size_is_refused(tmp_path: Path, kind) -> None:
    # Before: /dev/zero read to MemoryError; a FIFO hung (in the TUI, the UI froze).
    path = {"device": Path("/dev/zero"), "fifo": tmp_path / "rig.yaml",
            "huge": tmp_path / "big.yaml"}[kind]
    if kind == "fifo":
        os.mkfifo(path)
    if kind == "huge":
        path.write_text("notes: " + "x" * (5 << 20))
    with pytest.raises(InputError, match="not a regular file|too large"):
        create_session(tmp_path / "s", path)
    assert not (tmp_path / "s").exists()


# --------------------------------------------------------------------------- 3, 5: image bombs


def _png_declaring(path: Path, width: int, height: int) -> Path:
    """A small PNG whose header declares ``width`` x ``height`` (the data is one row)."""
    def chunk(kind: bytes, data: bytes) -> bytes:
        return struct.pack(">I", len(data)) + kind + data + \
            struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF)

    header = struct.pack(">IIBBBBB", width, height, 8, 0, 0, 0, 0)
    body = zlib.compress(b"\0" + bytes(width))
    path.write_bytes(b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", header) + chunk(b"IDAT", body)
                     + chunk(b"IEND", b""))
    return path


@pytest.mark.parametrize("size", [(32000, 32000), (18000, 18000), (60000, 60000), (1152, 864)])
def test_an_image_declaring_the_wrong_size_is_refused_before_decoding(tmp_path: Path, size,
                                                                     capfd) -> None:
    # Before: 2.1 GB then a traceback; an 18000x18000 frame accepted into raw/ at 3.6 GB;
    # a header of 60000x60000 an OpenCV traceback. Now refused from the header alone.
    import resource

    before = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    source = _png_declaring(tmp_path / "bomb.png", *size)
    session = new_session(tmp_path)
    with pytest.raises(InputError, match=rf"{size[0]}x{size[1]} px"):
        add_frame(session, "left", source)
    assert resource.getrusage(resource.RUSAGE_SELF).ru_maxrss - before < 200_000  # KB
    assert list((session.path / "raw").iterdir()) == []
    assert capfd.readouterr().err == ""


# --------------------------------------------------------------------------- 4: whole rows


def test_a_full_disk_during_a_log_append_leaves_the_log_as_it_was(tmp_path: Path,
                                                                  monkeypatch) -> None:
    log = tmp_path / LOG_NAME
    append_rows(log, [make_row("T1", 300.0, 0.5)])
    before = log.read_bytes()
    real_write = os.write

    def half_then_full(fd: int, data: bytes) -> int:
        real_write(fd, data[: len(data) // 2])
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(files.os, "write", half_then_full)
    with pytest.raises(OSError, match="No space left"):
        append_rows(log, [make_row("T2", 310.0, 0.2)])
    monkeypatch.undo()
    assert log.read_bytes() == before  # the half row was truncated away
    append_rows(log, [make_row("T3", 320.0, 0.1)])
    assert [row.target for row in read_rows(log)] == ["T1", "T3"]


def test_a_torn_last_row_is_reported_and_skipped(tmp_path: Path) -> None:
    # What an older rigkit left on a full disk: half a row, then the next run's rows
    # (glued onto the fragment before). The log stays readable.
    log = tmp_path / LOG_NAME
    append_rows(log, [make_row("T1", 300.0, 0.5)])
    with log.open("a") as handle:
        handle.write("20261123T100000Z,2026-11-23T10:00:00Z,field-1,T2,1000,8")
    torn: list[str] = []
    assert [row.target for row in read_rows(log, torn)] == ["T1"]
    assert torn == [f"{log}: the last line was cut short and was skipped"]
    append_rows(log, [make_row("T3", 320.0, 0.1)])
    torn.clear()
    assert [row.target for row in read_rows(log, torn)] == ["T1", "T3"]
    assert "line 3 is damaged and was skipped" in torn[0]


def test_a_full_tmpfs_during_processing_is_one_line(small_session: Path, tmp_path: Path,
                                                    capfd) -> None:
    import shutil

    needed = sum(p.stat().st_size for p in (small_session / "raw").iterdir()) + (256 << 10)
    mount = tmp_path / "small"
    mount.mkdir()
    if os.system(f"mount -t tmpfs -o size={needed} tmpfs {mount} 2>/dev/null") != 0:
        pytest.skip("cannot mount a tmpfs here")
    try:  # the session's frames fit; its 1.4 MB of results do not
        copy = mount / "seed-3"
        shutil.copytree(small_session, copy, ignore=shutil.ignore_patterns("ground_truth"))
        code = main(["process", str(copy)])
        err = capfd.readouterr().err
        assert code == 1 and "please report" not in err
        assert "the disk is nearly full" in err or "No space left" in err
        assert not (copy / "results").exists() and not list(copy.glob(".results*"))
    finally:
        os.system(f"umount {mount}")


# --------------------------------------------------------------------------- 8, 13: values


@pytest.mark.parametrize(
    "edit, message",
    [
        (lambda d: d["rig"].update(values=None), "rig.values: must be a mapping"),
        (lambda d: d["rig"].update(values=[1, 2]), "rig.values: must be a mapping"),
        (lambda d: d["rig"]["values"]["camera"].update(distortion={"k1": 1e300}),
         "rig.values.camera.distortion: moves the image corner"),
        (lambda d: d["rig"]["values"]["baselines"]["C_lr"].update(value_m=1e-12),
         "rig.values.baselines.C_lr.value_m: must be > 0.01"),
    ],
)
def test_absurd_rig_values_in_session_yaml_are_one_line(synth_session: Path, tmp_path: Path,
                                                        edit, message) -> None:
    copy = copy_session(synth_session, tmp_path, edit=edit)
    with pytest.raises(InputError, match=message):
        load_session(copy)


def test_hand_edited_sizes_windows_and_bursts_are_refused(synth_session: Path,
                                                          tmp_path: Path) -> None:
    def edit(data):
        data["frames"]["right"]["size_px"] = [640, 480]
        data["targets"][0]["window_px"] = 100001
        frame = data["frames"]["left"]
        data["frames"]["left"] = [frame, frame, frame]

    problems = "; ".join(frame_problems(load_session(copy_session(synth_session, tmp_path,
                                                                  edit=edit))))
    assert ("right frame raw/right.png is 640x480 px as session.yaml records it, the rig's "
            "image size 960x720") in problems
    assert "window 100001 px is larger than the 960x720 image" in problems
    assert "raw/left.png is the same file as raw/left.png, given twice in the burst" in problems


# --------------------------------------------------------------------------- 11, 14: crashes


def test_a_killed_copy_is_cleaned_by_the_next_change(tmp_path: Path) -> None:
    session = new_session(tmp_path)
    (session.path / ".staging").mkdir()
    (session.path / ".staging" / ".frame.1234abcd.png").write_bytes(b"half a frame")
    (session.path / "raw" / ".ingest.5678abcd.tmp").write_bytes(b"half of one from before")
    add_target(session, "T1", (10.0, 10.0), readings=[reading(300.0)])
    assert list((session.path / ".staging").iterdir()) == []
    assert list((session.path / "raw").iterdir()) == []


def test_a_swap_stopped_between_its_renames_is_undone_by_the_next_command(
    processed_small: Path, tmp_path: Path, capsys
) -> None:
    copy = copy_session(processed_small, tmp_path)
    results = copy / "results"
    before = sorted(p.name for p in results.iterdir())
    results.rename(copy / ".results-old-0001")  # the crash: retired, the new one not in
    (copy / ".results-0001").mkdir()
    assert main(["session", "show", str(copy)]) == 0
    assert sorted(p.name for p in results.iterdir()) == before
    assert not list(copy.glob(".results-*"))


def test_rows_lost_between_the_swap_and_the_log_are_appended(processed_small: Path,
                                                             tmp_path: Path) -> None:
    copy = copy_session(processed_small, tmp_path)
    run_rows = read_rows(copy / "results" / LOG_NAME)
    (copy / LOG_NAME).unlink()  # the crash: results/ swapped in, the log never written
    add_target(load_session(copy), "late", (100.0, 100.0), readings=[reading(300.0)])
    assert read_rows(copy / LOG_NAME) == run_rows
    assert "repair" in (copy / "history.log").read_text()


def test_a_damaged_copy_of_the_rows_in_results_blocks_nothing(
    processed_small: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """results/ is derived: a garbled comparisons.csv there is replaced by the next run,
    not a session that can no longer be processed."""
    copy = copy_session(processed_small, tmp_path)
    logged = (copy / LOG_NAME).read_bytes()
    (copy / "results" / LOG_NAME).write_text("garbage,,,\n")
    assert main(["process", str(copy)]) == 0
    assert "1 processed, 0 failed" in capsys.readouterr().out
    assert read_rows(copy / "results" / LOG_NAME)
    assert (copy / LOG_NAME).read_bytes().startswith(logged)


# --------------------------------------------------------------------------- 16, 17: paths


def test_a_frame_linking_out_of_the_session_is_refused(synth_session: Path,
                                                       tmp_path: Path) -> None:
    copy = copy_session(synth_session, tmp_path)
    outside = tmp_path / "elsewhere.png"
    (copy / "raw" / "back.png").rename(outside)
    (copy / "raw" / "back.png").symlink_to(outside)
    problems = frame_problems(load_session(copy))
    assert any("raw/back.png is a link to" in p and "outside the session" in p
               for p in problems)


@pytest.mark.parametrize("name", ["../../x", "/tmp/x", "a/b", ".hidden"])
def test_a_session_name_is_never_a_path(tmp_path: Path, name: str) -> None:
    (tmp_path / "capture").mkdir()
    with pytest.raises(InputError, match="session name"):
        create_session_in(tmp_path / "capture", name, rig_file(tmp_path, SIZE))
    assert sorted(p.name for p in tmp_path.iterdir()) == ["capture", "rig.yaml"]


# --------------------------------------------------------------------------- 7: plausible ranges


@pytest.mark.parametrize("typed", ["1e9", "1e300", "3_0_2.00", "3000000", "inf", "nan", "-5",
                                   "0"])
def test_implausible_typed_ranges_never_become_readings(tmp_path: Path, typed: str,
                                                        capsys) -> None:
    session = new_session(tmp_path)
    code = main(["session", "add-target", str(session.path), "--pixel", "10", "10",
                 "--range-m", typed])
    err = capsys.readouterr().err.strip()
    assert code == 2 and len(err.splitlines()) == 1 and "range" in err
    assert load_session(session.path).targets == ()


def test_a_frame_replaced_by_a_fifo_or_a_folder_is_said_as_such(synth_session: Path,
                                                                 tmp_path: Path) -> None:
    """Before: both were "missing", and a FIFO given as a session "no such session
    folder"."""
    import os

    session = copy_session(synth_session, tmp_path)
    (session / "raw" / "back.png").unlink()
    os.mkfifo(session / "raw" / "back.png")
    (session / "raw" / "right.png").unlink()
    (session / "raw" / "right.png").mkdir()
    problems = "; ".join(frame_problems(load_session(session)))
    assert "back frame raw/back.png is a FIFO, not the frame file" in problems
    assert "right frame raw/right.png is a folder, not the frame file" in problems
    os.mkfifo(tmp_path / "fifo")
    with pytest.raises(InputError, match="fifo: a FIFO, not a session folder"):
        load_session(tmp_path / "fifo")
