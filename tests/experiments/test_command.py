"""``rigkit experiments`` as a user drives it: files written, one-line errors."""

from __future__ import annotations

import csv
import json

import pytest

from rigkit.cli import main


@pytest.mark.slow
def test_table1_writes_four_rows_with_rigkit_best(tmp_path, capsys):
    pytest.importorskip("pycolmap")
    out = tmp_path / "t1"
    args = ["experiments", "table1", "--scenes", "2", "--width", "576", "--height", "432",
            "--out", str(out), "--quiet"]
    assert main(args) == 0
    with (out / "table1.csv").open() as fh:
        rows = {r["method"]: r for r in csv.DictReader(fh)}
    assert list(rows) == ["rigkit", "paper", "loop-zhang", "sfm-mvs"]
    assert set(rows["rigkit"]) == {"method", "failures", "lt05", "lt1", "lt2", "lt3", "bias"}
    lt1 = {m: float(r["lt1"]) if r["lt1"] != "nan" else 0.0 for m, r in rows.items()}
    assert rows["rigkit"]["failures"] == "0"
    assert lt1["rigkit"] > max(v for m, v in lt1.items() if m != "rigkit")
    assert (out / "table1.png").read_bytes()[:4] == b"\x89PNG"
    assert len((out / "table1_scenes.csv").read_text().splitlines()) == 1 + 4 * 2
    assert "sfm-mvs" in capsys.readouterr().out


def test_bas_relief_writes_runs_summary_and_figure(tmp_path, capsys):
    assert main(["experiments", "bas-relief", "--runs", "3", "--out", str(tmp_path)]) == 0
    assert len((tmp_path / "basrelief.csv").read_text().splitlines()) == 4
    assert json.loads((tmp_path / "basrelief.json").read_text())["runs"] == 3
    assert (tmp_path / "basrelief.png").is_file()
    assert "about y" in capsys.readouterr().out


def test_stereo_prints_bad_pixels(capsys):
    assert main(["experiments", "stereo", "--json"]) == 0
    assert 0 < json.loads(capsys.readouterr().out)["bad2_est"] < 0.1


@pytest.mark.parametrize(
    "args, message",
    [
        (["table1", "--scenes", "0"], "--scenes must be at least 1"),
        (["table1", "--scenes", "1", "--methods", "rigkit,colmap"], "unknown colmap"),
        (["table1", "--scenes", "1", "--width", "10"], "width=10 is out of range"),
        (["bas-relief", "--runs", "0"], "--runs must be at least 1"),
        (["bas-relief", "--noise", "-1"], "--noise must not be negative"),
    ],
)
def test_bad_arguments_are_one_line_errors(tmp_path, capsys, args, message):
    assert main(["experiments", *args, "--out", str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert message in err and len(err.strip().splitlines()) == 1 and "Traceback" not in err
    assert not (tmp_path / "table1.csv").exists()
