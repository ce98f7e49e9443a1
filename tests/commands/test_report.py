"""``rigkit report``: the files it writes, plot formats, one-line errors."""

from __future__ import annotations

from pathlib import Path

import cv2
import pytest

from rigkit import cli
from rigkit.capture.comparisons import LOG_NAME, read_rows
from tests.conftest import make_log as _session
from tests.conftest import make_row as _row


@pytest.fixture
def main(monkeypatch: pytest.MonkeyPatch):
    """cli.main with the report command registered (whether or not cli lists it yet)."""
    if "report" not in cli.COMMANDS:
        monkeypatch.setattr(cli, "COMMANDS", (*cli.COMMANDS, "report"))
    return cli.main


OUTPUTS = ("comparisons.csv", "report.txt", "estimate_vs_laser.png", "error_vs_range.png")


def test_report_command_writes_all_outputs(main, two_runs: Path, tmp_path: Path, capsys) -> None:
    other = _session(tmp_path, "field-2", [_row("T1", 510.0, 0.3, session="field-2")])
    out = tmp_path / "out" / "report"
    assert main(["report", str(two_runs), str(other), "--out", str(out)]) == 0
    stdout = capsys.readouterr().out
    assert sorted(p.name for p in out.iterdir()) == sorted([*OUTPUTS, ".rigkit-outputs"])
    report = (out / "report.txt").read_text()
    assert stdout.startswith(report) and "wrote " in stdout.splitlines()[-1]
    assert len(read_rows(out / "comparisons.csv")) == 5
    for name in OUTPUTS[2:]:
        img = cv2.imread(str(out / name))
        assert img is not None and img.shape == (700, 1000, 3)


def test_report_command_all_runs(main, two_runs: Path, tmp_path: Path) -> None:
    out = tmp_path / "out"
    assert main(["report", str(two_runs), "--out", str(out), "--all-runs"]) == 0
    assert len(read_rows(out / "comparisons.csv")) == 6


def _empty_log(session: Path) -> Path:
    """A folder beside ``session`` whose log holds its header and nothing else."""
    empty = session.parent / "empty"
    empty.mkdir()
    (empty / LOG_NAME).write_text(((session / LOG_NAME).read_text().splitlines()[0]) + "\n")
    return empty


@pytest.mark.parametrize(
    "args, message",
    [
        (lambda s, t: [str(t / "missing")], "missing: no such session folder"),
        (lambda s, t: [], "no session folders given"),
        (lambda s, t: [str(s), "--out", str(s)], "inside the session"),
        (lambda s, t: [str(s), "--out", str(s / "reports")], "inside the session"),
        (lambda s, t: [str(_empty_log(s))], "no comparisons in"),
    ],
    ids=["missing-session", "no-session", "out-is-session", "out-in-session", "empty-log"],
)
def test_report_command_errors_are_one_line(
    main, two_runs: Path, tmp_path: Path, capsys, args, message
) -> None:
    argv = ["report", *args(two_runs, tmp_path)]
    if "--out" not in argv:
        argv += ["--out", str(tmp_path / "out")]
    log_before = (two_runs / LOG_NAME).read_bytes()
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("rigkit report: error: ") and message in err
    assert len(err.splitlines()) == 1
    assert not (tmp_path / "out").exists()
    assert (two_runs / LOG_NAME).read_bytes() == log_before


def test_report_command_writes_each_plot_format(main, two_runs: Path, tmp_path: Path) -> None:
    out = tmp_path / "out"
    assert main(["report", str(two_runs), "--out", str(out), "--format", "svg,pdf,png"]) == 0
    names = sorted(p.name for p in out.iterdir())
    assert names == sorted(
        ["comparisons.csv", "report.txt", ".rigkit-outputs"]
        + [f"{stem}.{fmt}" for stem in ("estimate_vs_laser", "error_vs_range")
           for fmt in ("png", "svg", "pdf")]
    )
    assert (out / "error_vs_range.pdf").read_bytes().startswith(b"%PDF")
    assert b"<svg" in (out / "estimate_vs_laser.svg").read_bytes()[:500]


def test_report_command_rejects_an_unknown_format(main, two_runs: Path, tmp_path: Path,
                                                  capsys) -> None:
    assert main(["report", str(two_runs), "--out", str(tmp_path / "out"), "--format", "gif"]) == 2
    assert "--format gif: expected one or more of png, svg, pdf" in capsys.readouterr().err
    assert not (tmp_path / "out").exists()
