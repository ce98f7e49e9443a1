"""`rigkit rig calibrate` and `rigkit session set-rig` on a rendered session whose
profile has C_lb taped 1.5 % short: the lasers find it, the written profile fixes the
depth maps' scale against the ground truth, and every front end says what the lasers
imply."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from rigkit.batch import process_session
from rigkit.capture import load_session
from rigkit.capture.results import stale_results
from rigkit.cli import main
from rigkit.rig import load_rig
from rigkit.synth.evaluate import evaluate_scene
from tests.conftest import copy_session

SHORT = 0.985  # the profile's C_lb against the truth


def _short_c_lb(data: dict) -> None:
    data["rig"]["values"]["baselines"]["C_lb"] = {"value_m": 2.0 * SHORT, "tolerance_m": 0.02}


def _bias_pct(session: Path) -> float:
    return 100 * evaluate_scene(session, session / "results" / "depth.npy").median_bias


@pytest.fixture(scope="module")
def short_session(synth_session: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """``synth_session`` with C_lb 1.5 % short in its profile, processed (read-only)."""
    out = copy_session(synth_session, tmp_path_factory.mktemp("short"), edit=_short_c_lb)
    assert process_session(out, "20260101T000000Z-0001").ok
    return out


@pytest.mark.slow
def test_calibrating_fixes_the_scale_a_short_tape_gave(
    short_session: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    session = copy_session(short_session, tmp_path)
    before = _bias_pct(session)
    assert before < -1.0  # the short tape shows in the map
    out = tmp_path / "calibrated.yaml"
    assert main(["rig", "calibrate", str(session), "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    assert "fitted from 5 laser target(s) in 1 session(s)" in printed
    assert "checked: 5/5 targets within 1 % of their laser" in printed
    calibrated = load_rig(out).baseline_lb
    assert abs(calibrated.value_m - 2.0) < 2 * calibrated.tolerance_m  # the truth, within 2σ
    assert main(["session", "set-rig", str(session), "--rig", str(out)]) == 0
    assert "before the rig changed" in (stale_results(load_session(session)) or "")
    assert "set-rig" in (session / "history.log").read_text()
    assert main(["process", str(session)]) == 0
    printed = capsys.readouterr()
    assert "scale: lasers say C_lb = " in printed.err and ": consistent" in printed.err
    assert abs(_bias_pct(session)) < 0.5 < abs(before) / 2


def test_process_and_report_say_what_the_lasers_imply(
    short_session: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert main(["report", str(short_session), "--out", str(tmp_path / "report")]) == 0
    line = next(x for x in capsys.readouterr().out.splitlines() if x.startswith("scale of"))
    said = re.search(r"lasers say C_lb = ([\d.]+) \+- ([\d.]+) m", line)
    assert said is not None and "the profile says 1.970 +- 0.020 m" in line
    c_lb, sigma = float(said[1]), float(said[2])
    assert abs(c_lb - 2.0) < 2 * sigma < abs(c_lb - 2.0 * SHORT)  # the truth, not the tape
    assert line.endswith("re-tape C_lb, or calibrate (rigkit rig calibrate)")


def test_calibrate_refuses_what_it_cannot_use(
    synth_session: Path, short_session: Path, processed_session: Path, tmp_path: Path,
    capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "rig.yaml"
    assert main(["rig", "calibrate", str(synth_session), "--out", str(out)]) == 2
    assert "not processed with laser targets yet" in capsys.readouterr().err
    two = [str(short_session), str(processed_session)]  # C_lb 1.97 and 2.00 m
    assert main(["rig", "calibrate", *two, "--out", str(out)]) == 2
    assert "its rig differs" in capsys.readouterr().err
    out.write_text("keep me")
    assert main(["rig", "calibrate", str(short_session), "--out", str(out)]) == 2
    assert "exists; give --force" in capsys.readouterr().err
    assert out.read_text() == "keep me" and not list(tmp_path.glob("*.tmp*"))


def test_set_rig_refuses_a_profile_for_other_frames(short_session: Path, tmp_path: Path,
                                                    capsys: pytest.CaptureFixture[str]) -> None:
    session = copy_session(short_session, tmp_path)
    before = (session / "session.yaml").read_bytes()
    root = Path(__file__).resolve().parents[2]
    assert main(["session", "set-rig", str(session), "--rig",
                 str(root / "rigs" / "p1000-tripod.yaml")]) == 2
    assert "the session's are 960x720 px" in capsys.readouterr().err
    assert (session / "session.yaml").read_bytes() == before
