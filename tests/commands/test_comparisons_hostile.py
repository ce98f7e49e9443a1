"""A session's comparisons log is input like any other, though rigkit wrote it (issue
46): a log larger than any run writes is refused unread, in one line naming it and the
limit; a row with a range no rangefinder gives (1e150 m, 1e200 m, NaN) is skipped and
said by what shows the history (session show, report) and refused by what would fit a
rig from it (rig calibrate): never a traceback, never a fitted rig."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import pytest

from rigkit.capture.comparisons import LOG_LIMIT, LOG_NAME, append_rows, csv_text, read_rows
from rigkit.cli import main
from tests.conftest import copy_session


@pytest.fixture
def session(processed_session: Path, tmp_path: Path) -> Path:
    return copy_session(processed_session, tmp_path)


def _one_line(capsys: pytest.CaptureFixture[str]) -> str:
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1, err
    return err


def test_a_log_larger_than_any_run_writes_is_not_read(
    session: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Before: a 3 GB log was read whole: MemoryError in all three commands. The log and
    the current run's copy in results/ (what a report and a calibration read) alike."""
    for log in (session / LOG_NAME, session / "results" / LOG_NAME):
        with log.open("r+b") as handle:
            handle.truncate(3 << 30)  # sparse: no disk used
    limit = f"more than the {LOG_LIMIT >> 20} MB a comparisons log can be"
    assert main(["session", "show", str(session)]) == 0  # shown, with the warning
    captured = capsys.readouterr()
    assert f"{session / LOG_NAME}: 3 GB, {limit}" in captured.err
    assert len(captured.err.strip().splitlines()) == 1 and captured.out.startswith("session")
    for command in (["report", str(session), "--out", str(tmp_path / "report"), "--all-runs"],
                    ["report", str(session), "--out", str(tmp_path / "report")],
                    ["rig", "calibrate", str(session), "--out", str(tmp_path / "rig.yaml")]):
        assert main(command) == 2
        err = _one_line(capsys)
        assert LOG_NAME in err and f"3 GB, {limit}" in err
    assert not (tmp_path / "rig.yaml").exists() and not (tmp_path / "report").exists()


def _hostile(session: Path, laser_m: float, estimate_m: float) -> None:
    """Every usable row of the current run given these ranges, its errors made to follow
    from them (so only the ranges are wrong): in the run's own copy (``results/``, what
    a calibration fits) and appended to the log as a newer run (what is shown)."""
    current = session / "results" / LOG_NAME
    rows = read_rows(current)
    error = estimate_m - laser_m
    bad = [replace(row, laser_range_m=laser_m, estimate_range_m=estimate_m, error_m=error,
                   error_pct=100 * error / laser_m) if row.ok else row for row in rows]
    current.write_text(csv_text(bad))
    append_rows(session / LOG_NAME, [replace(row, run_id="29990101T000000Z-0001")
                                     for row in bad])


@pytest.mark.parametrize("laser_m, estimate_m", [(1e150, 1e150), (1e200, 300.0),
                                                 (300.0, 1e200)])
def test_ranges_beyond_any_rangefinder_fit_no_rig(
    session: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str],
    laser_m: float, estimate_m: float,
) -> None:
    """Before: rows at 1e150 m were tracebacks, and 300 m against 1e200 m made
    rig calibrate write C_lb = 0.0102 m with exit status 0."""
    _hostile(session, laser_m, estimate_m)
    out = tmp_path / "rig.yaml"
    assert main(["rig", "calibrate", str(session), "--out", str(out)]) == 2
    err = _one_line(capsys)
    assert f"{LOG_NAME}" in err and "line 2 is no comparison" in err and "is no range" in err
    assert not out.exists()
    assert main(["session", "show", str(session)]) == 0
    assert "is damaged and was skipped" in capsys.readouterr().err
    report = tmp_path / "report"
    assert main(["report", str(session), "--out", str(report), "--all-runs"]) == 0
    captured = capsys.readouterr()
    assert "is damaged and was skipped" in captured.err and "e+150" not in captured.out
    assert "e+200" not in (report / "report.txt").read_text()


def test_a_line_longer_than_csv_splits_and_many_damaged_lines_are_said_briefly(
    session: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Before: a field over 128 KiB raised csv's own error out of every reader (a
    traceback in report, session show and rig calibrate); 2,000 damaged rows printed
    2,000 warnings."""
    log = session / LOG_NAME
    with log.open("a") as handle:
        handle.write("x" * 200_000 + "\n")
        handle.writelines(f"damaged,{n}\n" for n in range(2000))
    assert main(["session", "show", str(session)]) == 0
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 6 and "... and 1996 more like these" in err[-1], err
    assert "line" in err[0] and "field larger than field limit" in err[0], err[0]
    assert main(["report", str(session), "--out", str(tmp_path / "report"), "--all-runs"]) == 0
    assert len(capsys.readouterr().err.strip().splitlines()) == 6
    for damaged in (log, session / "results" / LOG_NAME):  # a header beyond what csv splits
        damaged.write_text("y" * 200_000 + "\n")
    for command in (["rig", "calibrate", str(session), "--out", str(tmp_path / "rig.yaml")],
                    ["report", str(session), "--out", str(tmp_path / "r2"), "--all-runs"]):
        assert main(command) == 2
        assert "not a comparisons log" in _one_line(capsys)
