"""``rigkit rig check``: the text table, JSON output and exit codes."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from rigkit.cli import main
from rigkit.rig import ErrorModel, budget_row, load_rig
from tests.rig.test_budget import P1000, _profile

# --------------------------------------------------------------------------- the command


def test_cli_table_for_the_p1000(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["rig", "check", str(P1000), "--offset-error-px", "0.5"]) == 1  # a warning
    out = capsys.readouterr().out
    assert "53,251 px +-1 %" in out
    assert "4.95 x 3.72 deg" in out
    assert "one camera moved between the positions" in out  # the profile's one_camera
    assert "1/150" in out and "0.382" in out  # at the profile's nominal 300 m
    # 0.25 px disparity, 0.5 px offset and 0.48 px from a lens fitted to 0.5 px at the
    # corner: a = 0.74 px / (f C_lr); b = 1.73 %; z = sqrt(0.03^2 - b^2) / a.
    assert "3 % depth error: reached at 3,528 m" in out
    assert "lens           none given; fitted from the three views" in out
    assert "offset: as given (--offset-error-px)." in out
    # 1 % is out of reach at every range (the tolerances alone give 1.73 %): a warning,
    # never "warnings: none" under a table that says so.
    assert "warnings (1):" in out and "1 % depth error is out of reach at every range" in out


@pytest.mark.parametrize(
    ("args", "offset_px", "reach"),
    [
        # Moderate air at the P1000's 53,251 px: 6.8 urad = 0.363 px RMS over 1.05 mrad
        # = 55.8 px, 1.21 times the 1 % of the width the figures were measured at; one
        # frame: hypot(0.37, 2.8 x 0.363 x 1.21) = 1.29 px.
        ([], 1.287, "1,867 m"),
        # Five frames: the shimmer's share over sqrt(5), hypot(0.37, 1.232 / sqrt(5)).
        (["--frames", "5"], 0.664, "3,038 m"),
        # No shimmer: what the principal points leave.
        (["--shimmer-px", "0"], 0.37, "3,961 m"),
        # Shimmer correlated over 2 % of the width: its share is twice the measured,
        # hypot(0.37, 2.8 x 0.363 x 2).
        (["--shimmer-corr-px", "92.16"], 2.068, "1,220 m"),
    ],
)
def test_cli_offset_from_frames_and_shimmer(
    args: list[str], offset_px: float, reach: str | None, capsys: pytest.CaptureFixture[str]
) -> None:
    assert main(["rig", "check", str(P1000), *args]) == 1
    out = capsys.readouterr().out
    assert f"{offset_px:.2g} px" in out
    if reach:
        assert f"3 % depth error: reached at {reach}" in out
    assert main(["rig", "check", str(P1000), *args, "--json"]) == 1
    assumptions = json.loads(capsys.readouterr().out)["assumptions"]
    assert assumptions["offset_error_px"] == pytest.approx(offset_px, abs=1e-3)
    assert assumptions["offset_frames_per_position"] == (5 if "5" in args else 1)


def test_cli_reports_the_correlation_length_it_budgeted_for(
    capsys: pytest.CaptureFixture[str],
) -> None:
    assert main(["rig", "check", str(P1000), "--shimmer-corr-px", "51"]) == 1
    assert "0.36 px RMS of heat shimmer over 51 px" in capsys.readouterr().out
    with pytest.raises(SystemExit) as exc:
        main(["rig", "check", str(P1000), "--shimmer-corr-px", "0"])
    assert exc.value.code == 2
    assert "--shimmer-corr-px: must be > 0 and <= 1e+06 px, got 0" in capsys.readouterr().err


def test_cli_rejects_no_frames(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as exc:
        main(["rig", "check", str(P1000), "--frames", "0"])
    assert exc.value.code == 2
    assert "--frames: must be at least 1, got 0" in capsys.readouterr().err


def test_cli_json_and_warning_exit_code(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = _profile(tmp_path, 13_000, 0.5, 0.3)
    assert main(["rig", "check", str(path), "--range", "250", "--range", "500", "--json"]) == 1
    data = json.loads(capsys.readouterr().out)
    assert data["focal_px"] == 13_000
    assert [g["range_m"] for g in data["geometry"]] == [250.0, 500.0]
    assert len(data["error_budget"]) == 9
    assert data["error_budget"][0]["total_m"] == pytest.approx(
        budget_row(ErrorModel.from_profile(load_rig(path)), 100.0).total_m
    )
    assert {w["code"] for w in data["warnings"]} >= {"C_lb_too_small", "fov_too_wide"}


def test_cli_rejects_a_negative_range(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as caught:
        main(["rig", "check", str(P1000), "--range", "-5"])
    assert caught.value.code == 2
    assert "--range: must be >= 1 and <= 100000 m, got -5" in capsys.readouterr().err
