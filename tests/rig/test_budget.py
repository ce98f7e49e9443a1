"""The rig check: error budget against the formulas, geometry warnings."""

from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path
from typing import Any

import pytest

from rigkit.errors import InputError
from rigkit.reporting.rig_check import format_check
from rigkit.rig import Baseline, load_rig
from rigkit.rig.budget import ErrorModel, budget_row, range_reaching
from rigkit.rig.bursts import burst_warning, expected_offset_error_px, frames_for_offset
from rigkit.rig.check import check_rig
from rigkit.rig.formulas import (
    affine_residual_px,
    anchor_error_fraction,
    back_shift_px,
    depth_error_from_disparity,
    disparity_px,
    triangulation_angle_deg,
)

ROOT = Path(__file__).resolve().parents[2]
P1000 = ROOT / "rigs" / "p1000-tripod.yaml"
VEHICLE = ROOT / "rigs" / "vehicle-2m.yaml"
SYNTHETIC = ROOT / "rigs" / "synthetic.yaml"
P1000_FOCAL_PX = 400.0 * 1.25 * 4608 / math.hypot(36.0, 24.0)  # 53,251.2 px

def _model(**changes: Any) -> ErrorModel:
    values: dict[str, Any] = {
        "focal_px": P1000_FOCAL_PX,
        "focal_tolerance": 0.01,
        "baseline_lr": Baseline(2.0, 0.02),
        "baseline_lb": Baseline(2.0, 0.02),
        "disparity_error_px": 0.25,
        "offset_error_px": 0.5,
    }
    values.update(changes)
    return ErrorModel(**values)


def _profile(tmp_path: Path, focal_px: float, lr: float, lb: float) -> Path:
    path = tmp_path / "rig.yaml"
    path.write_text(
        f"""version: 1
name: test
camera:
  model: test camera
  resolution: [4608, 3456]
  focal_length: {{px: {focal_px}, tolerance_fraction: 0.005}}
baselines:
  C_lr: {{value_m: {lr}, tolerance_m: 0.001}}
  C_lb: {{value_m: {lb}, tolerance_m: 0.001}}
""",
        encoding="utf-8",
    )
    return path


# --------------------------------------------------------------------------- formulas


def test_disparity_and_triangulation_angle_of_the_synthetic_protocol() -> None:
    # Paper Sec. 4.2: baseline/depth 1/150, intersection angle ~0.382 deg.
    focal = 2304 / math.tan(math.radians(3.0))
    assert disparity_px(300.0, focal, 2.0) == pytest.approx(293.09, abs=0.01)
    assert triangulation_angle_deg(300.0, 2.0) == pytest.approx(0.382, abs=5e-4)


def test_depth_error_from_disparity_hand_computed() -> None:
    # dz = z^2 dd / (f C_lr) = 300^2 * 0.25 / (53,251.2 * 2) = 22,500 / 106,502.4 = 0.21126 m.
    assert depth_error_from_disparity(300.0, P1000_FOCAL_PX, 2.0, 0.25) == pytest.approx(
        0.21126, abs=1e-5
    )


@pytest.mark.parametrize("range_m", [100.0, 250.0, 500.0])
def test_budget_row_follows_the_formulas(range_m: float) -> None:
    model = _model()
    row = budget_row(model, range_m)
    f_c = P1000_FOCAL_PX * 2.0
    assert row.disparity_px == pytest.approx(f_c / range_m)
    assert row.from_disparity_m == pytest.approx(range_m**2 * 0.25 / f_c)
    assert row.from_offset_m == pytest.approx(range_m**2 * 0.5 / f_c)
    assert row.from_baseline_lr_m == pytest.approx(range_m * 0.02 / 2.0)
    assert row.from_baseline_lb_m == pytest.approx(range_m * 0.02 / 2.0)
    assert row.from_focal_m == pytest.approx(range_m * 0.01)
    parts = (row.from_disparity_m, row.from_offset_m, 3 * (range_m * 0.01) ** 2)
    expected = math.sqrt(parts[0] ** 2 + parts[1] ** 2 + parts[2])
    assert row.total_m == pytest.approx(expected)
    assert row.total_fraction == pytest.approx(expected / range_m)


def test_budget_at_250_m_hand_computed() -> None:
    row = budget_row(_model(), 250.0)
    assert row.from_disparity_m == pytest.approx(0.1467, abs=1e-4)  # 15,625 / 106,502.4
    assert row.from_focal_m == pytest.approx(2.5)
    assert row.total_m == pytest.approx(4.34, abs=0.005)


def test_range_reaching_is_where_the_total_crosses_the_fraction() -> None:
    model = _model(
        focal_tolerance=0.002, baseline_lr=Baseline(2.0, 0.002), baseline_lb=Baseline(2.0, 0.002)
    )
    for fraction in (0.01, 0.03):
        range_m = range_reaching(model, fraction)
        assert range_m is not None and range_m > 0
        assert budget_row(model, range_m).total_fraction == pytest.approx(fraction)
        assert budget_row(model, 0.9 * range_m).total_fraction < fraction


def test_range_reaching_when_tolerances_alone_exceed_it() -> None:
    # b = sqrt(3) * 1 % = 1.73 % > 1 %: exceeded at every range.
    assert range_reaching(_model(), 0.01) == 0.0
    assert range_reaching(_model(), 0.03) == pytest.approx(4666.7, abs=0.1)


def test_range_reaching_without_range_dependent_errors_is_never() -> None:
    model = _model(disparity_error_px=0.0, offset_error_px=0.0)
    assert range_reaching(model, 0.03) is None


def test_offset_error_from_frames_and_shimmer() -> None:
    full = (4608, 3456)
    # The floor (principal points) and the shimmer's share (2.8 px per px), RSS.
    assert expected_offset_error_px(full) == pytest.approx(math.hypot(0.37, 0.84))
    assert expected_offset_error_px(full, frames=4) == pytest.approx(math.hypot(0.37, 0.42))
    assert expected_offset_error_px(full, shimmer_px=0.0) == pytest.approx(0.37)
    # A quarter-size image: the floor in its pixels is a quarter, the shimmer is given
    # in its pixels already.
    assert expected_offset_error_px((1152, 864), shimmer_px=0.0) == pytest.approx(0.0925)
    with pytest.raises(InputError, match="frames per position must be >= 1, got 0"):
        expected_offset_error_px(full, frames=0)


def test_offset_error_grows_with_the_shimmers_correlation_length() -> None:
    full = (4608, 3456)
    # Measured at 1 % of the width (46 px); twice the length, half as many patches
    # per side: twice the shimmer's share (benchmarks/offset_bound.py: x1.9).
    assert expected_offset_error_px(full, shimmer_corr_px=46.08) == pytest.approx(
        expected_offset_error_px(full))
    assert expected_offset_error_px(full, shimmer_corr_px=92.16) == pytest.approx(
        math.hypot(0.37, 1.68))
    with pytest.raises(InputError, match="correlation must be > 0 px"):
        expected_offset_error_px(full, shimmer_corr_px=0.0)


def test_frames_for_offset_is_the_shortest_burst_within_the_bar_nine_times_in_ten() -> None:
    full = (4608, 3456)
    at_300m = 293.0  # px of disparity at 300 m for the field scenes' f C_lr
    # 0.3 % of it is 0.88 px, 1.645 sigma: sigma <= 0.535 px. One frame at 0.3 px of
    # shimmer leaves 0.92 px; five 0.53 px (measured on bursts of five: 0.46 px).
    assert frames_for_offset(full, at_300m, 0.3) == 5
    assert frames_for_offset(full, at_300m, 0.0) == 1
    n = frames_for_offset(full, at_300m, 0.6)
    assert n is not None
    limit = 0.003 * at_300m / 1.645
    assert expected_offset_error_px(full, n, 0.6) <= limit
    assert expected_offset_error_px(full, n - 1, 0.6) > limit
    # Where the floor alone (0.37 px) is beyond that, no burst helps.
    assert frames_for_offset(full, 176.0, 0.3) is None  # 500 m


def test_burst_warning_only_for_a_burst_shorter_than_the_shimmer_calls_for() -> None:
    from rigkit.pipeline.shimmer import Shimmer

    rig = load_rig(SYNTHETIC)  # 4608x3456, f 43962.9 px, C_lr 2 m
    shimmer = Shimmer(rms_px=0.3, corr_px=46.08, tracker_px=0.05, points=1900)
    # At 300 m: 5 frames per position (above).
    assert burst_warning(rig, shimmer, "left frames 1 and 2", 300.0, 5) is None
    text = burst_warning(rig, shimmer, "left frames 1 and 2", 300.0, 3)
    assert text == ("heat shimmer 0.30 px RMS in patches of ~46 px (left frames 1 and 2): "
                    "take 5 frames per "
                    "position to keep the offset within 0.3 % of depth at 300 m (9 times in "
                    "10); this capture has 3")
    far = burst_warning(rig, shimmer, "left frames 1 and 2", 500.0, 64)
    assert far is not None and "at 500 m no burst keeps the offset within 0.3 %" in far
    assert burst_warning(rig, shimmer, "left frames 1 and 2", float("nan"), 1) is None


def test_the_profile_model_budgets_one_frame_unless_told(tmp_path: Path) -> None:
    profile = load_rig(P1000)
    derived = ErrorModel.from_profile(profile)
    # Moderate air (6.8 urad RMS over 1.05 mrad) at the P1000's 53,251 px: 0.363 px over
    # 55.8 px, 1.21 times the patches of the measured figure.
    share = 2.8 * 0.3 * 53251.2 / 43962.94 * (46.08 * 53251.2 / 43962.94 / 46.08)
    assert derived.offset_error_px == pytest.approx(math.hypot(0.37, share), rel=1e-4)
    assert derived.frames == 1 and derived.shimmer_px == pytest.approx(0.3634, abs=1e-4)
    burst = ErrorModel.from_profile(profile, frames=5)
    assert burst.offset_error_px < derived.offset_error_px
    given = ErrorModel.from_profile(profile, offset_error_px=0.5)
    assert given.offset_error_px == 0.5 and given.frames is None


def test_back_camera_anchor_hand_computed() -> None:
    # m_l - m_b = 2304 * 2 / 302 = 15.258 px; one pair: sqrt(2) * 0.25 / 15.258 = 2.32 %.
    assert back_shift_px(300.0, 2.0, 2304.0) == pytest.approx(15.258, abs=1e-3)
    assert anchor_error_fraction(300.0, 2.0, 2304.0, 0.25) == pytest.approx(0.02317, abs=1e-5)


def test_affine_residual_hand_computed() -> None:
    # 1 deg * 2304 * 1728 / 53,251.2 = 0.0174533 * 74.765 = 1.3049 px.
    assert affine_residual_px(P1000_FOCAL_PX, (4608, 3456), 1.0) == pytest.approx(1.3049, abs=1e-4)


# --------------------------------------------------------------------------- geometry warnings


@pytest.mark.parametrize("path", [P1000, VEHICLE, SYNTHETIC], ids=lambda path: path.stem)
def test_shipped_rigs_work_from_100_to_500_m(path: Path) -> None:
    """No geometry warning; where the tolerances alone exceed 1 % of depth (a tape's 2 cm
    on 2 m, a lens spec's 1 %), that one warning, which calibration answers."""
    check = check_rig(load_rig(path), [100.0, 200.0, 300.0, 400.0, 500.0])
    tolerances_alone = check.model.constant_term > 0.01
    assert [f.code for f in check.findings] == (["budget"] if tolerances_alone else [])
    assert [row.range_m for row in check.budget] == [100.0 + 50 * i for i in range(9)]


def test_small_baselines_and_wide_fov_are_flagged(tmp_path: Path) -> None:
    # 20 deg FOV (f = 13,000 px), C_lr 0.5 m, C_lb 0.3 m.
    profile = load_rig(_profile(tmp_path, 13_000, 0.5, 0.3))
    check = check_rig(profile, [100.0, 500.0])
    codes = [finding.code for finding in check.findings]
    # At 100 m: 0.25 px is 0.38 % (fine), one anchor pair 5.1 % (fine); at 500 m both fail.
    assert codes == ["C_lr_too_small", "C_lb_too_small", "fov_too_wide"]
    assert "at 500 m" in check.findings[0].message
    assert "C_lb = 0.3 m is too small" in check.findings[1].message
    assert "20.1 x 15.1 deg" in check.findings[2].message


def test_too_close_for_overlap_is_flagged(tmp_path: Path) -> None:
    profile = load_rig(_profile(tmp_path, 53_000, 2.0, 2.0))
    check = check_rig(profile, [40.0])  # disparity 2,650 px of 4,608: 42 % overlap
    assert [finding.code for finding in check.findings] == ["overlap"]
    assert "overlap by only 42 %" in check.findings[0].message


def test_lens_error_enters_the_budget(tmp_path: Path) -> None:
    # Fitted from the views (the default): the self-calibration's corner error, 0.5 px
    # at 4608 x 3456, seen by views turned 1 deg: dd = 3 * 0.5 * f tan(1 deg) / r_c.
    profile = load_rig(_profile(tmp_path, P1000_FOCAL_PX, 2.0, 2.0))
    model = check_rig(profile, [300.0]).model
    r_c = math.hypot(4608, 3456) / 2
    expected = 3 * 0.5 * P1000_FOCAL_PX * math.tan(math.radians(1.0)) / r_c
    assert model.lens_corner_px == pytest.approx(0.5)
    assert model.lens_error_px == pytest.approx(expected)
    row = budget_row(model, 300.0)
    assert row.from_lens_m == pytest.approx(depth_error_from_disparity(300.0, P1000_FOCAL_PX,
                                                                      2.0, expected))
    assert row.total_m > budget_row(replace(model, lens_error_px=0.0), 300.0).total_m
    # Held fixed with no distortion given: nothing to add, and the lens line says so.
    text = profile.source.read_text() + "pipeline: {distortion_terms: 0}\n"
    profile.source.write_text(text)
    fixed = check_rig(load_rig(profile.source), [300.0])
    assert fixed.model.lens_error_px == 0.0
    assert "not fitted" in format_check(fixed)


def test_ranges_must_be_positive() -> None:
    with pytest.raises(InputError, match="ranges must be > 0 m"):
        check_rig(load_rig(P1000), [0.0])


def test_a_laser_calibrated_profile_uses_its_calibrated_tolerances() -> None:
    """The P1000 with C_lb calibrated to 0.2 % at 300 m (f and C_lr left at 1 % each):
    f and C_lr only stretch depth about the depth the calibration pinned, so 1 % is in
    reach there (on 81dfff3 `rig check` said "1 % out of reach at every range")."""
    from rigkit.rig.provenance import Calibration, CalibrationSource

    taped = load_rig(ROOT / "rigs" / "p1000-tripod.yaml")
    source = CalibrationSource("ridge", "/data/ridge", "ab" * 32, "run", "2026:04:12", {})
    calibrated = replace(taped, baseline_lb=Baseline(2.0, 0.004),
                         calibration=Calibration("2026-04-13T09:00:00Z", taped.name,
                                                 (source,), 300.0))
    assert any(f.code == "budget" for f in check_rig(taped, [300.0]).findings)
    assert not any(f.code == "budget" for f in check_rig(calibrated, [300.0]).findings)
    model = ErrorModel.from_profile(calibrated)
    at_anchor = budget_row(model, 300.0)
    assert at_anchor.from_focal_m == 0.0 and at_anchor.from_baseline_lr_m == 0.0
    assert at_anchor.from_baseline_lb_m == pytest.approx(300.0 * 0.002)
    assert budget_row(model, 150.0).from_focal_m == pytest.approx(150.0 * 0.01 * 0.5)
    reach = range_reaching(model, 0.01)
    assert reach is not None and reach > 300.0
    total = budget_row(model, reach).total_fraction
    assert total == pytest.approx(0.01, rel=1e-6)  # the root is where it reaches 1 %
