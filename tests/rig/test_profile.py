"""Rig profiles: focal-length conversions, shipped profiles, invalid profiles."""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable
from pathlib import Path

import pytest

from rigkit.cli import main
from rigkit.errors import InputError
from rigkit.rig import (
    Baseline,
    CameraSpec,
    dump_rig,
    focal_px_from_35mm_equivalent,
    focal_px_from_mm,
    fov_deg,
    load_rig,
)
from rigkit.rig.profile import rig_to_dict

ROOT = Path(__file__).resolve().parents[2]
SHIPPED = sorted((ROOT / "rigs").glob("*.yaml"))
BAD = sorted((ROOT / "tests" / "data" / "bad_rigs").glob("*.yaml"))

P1000_SENSOR_MM = (6.17, 6.17 * 3456 / 4608)  # 6.17 x 4.6275 mm, the 4:3 image area
P1000_RESOLUTION = (4608, 3456)


# --------------------------------------------------------------------------- conversions


def test_focal_px_from_mm_full_frame() -> None:
    # 50 mm on a 36 mm wide sensor imaged at 6000 px: 50 * 6000 / 36 = 8333.33 px.
    assert focal_px_from_mm(50.0, 36.0, 6000) == pytest.approx(8333.333, abs=1e-3)


def test_focal_px_from_mm_p1000_zoom_end() -> None:
    # Nikon's 539 mm long end on a 6.17 mm wide, 4608 px image: 2,483,712 / 6.17.
    assert focal_px_from_mm(539.0, 6.17, 4608) == pytest.approx(402_546.5, abs=0.1)


def test_equivalent_on_full_frame_is_the_real_focal_length() -> None:
    # Crop factor 1 on 36 x 24 mm: 50 mm-equivalent is 50 mm, 8333.33 px at 6000 px.
    assert focal_px_from_35mm_equivalent(50.0, (36.0, 24.0), (6000, 4000)) == pytest.approx(
        8333.333, abs=1e-3
    )


def test_equivalent_p1000_worked_example() -> None:
    # Hand computation (docs/rig-profiles.md): diagonal sqrt(6.17^2 + 4.6275^2) = 7.7125 mm,
    # crop 43.2666 / 7.7125 = 5.60993, f = 400 / 5.60993 = 71.3021 mm,
    # f_px = 71.3021 * 4608 / 6.17 = 53,251.2 px.
    focal = focal_px_from_35mm_equivalent(400.0, P1000_SENSOR_MM, P1000_RESOLUTION)
    assert focal == pytest.approx(53_251.2, abs=0.1)
    assert focal * 6.17 / 4608 == pytest.approx(71.302, abs=1e-3)  # back to real mm


def test_width_shortcut_is_four_percent_off_on_4_3() -> None:
    # The shortcut f_px = f_eq * width_px / 36 = 400 * 4608 / 36 = 51,200 px is 4.0 % short,
    # which at 250 m is a 10 m depth error (depth scales with f).
    correct = focal_px_from_35mm_equivalent(400.0, P1000_SENSOR_MM, P1000_RESOLUTION)
    shortcut = 400.0 * 4608 / 36.0
    assert shortcut == 51_200.0
    assert correct / shortcut - 1 == pytest.approx(0.0401, abs=1e-4)
    assert 250.0 * (correct / shortcut - 1) == pytest.approx(10.0, abs=0.05)


def test_equivalent_depends_only_on_sensor_aspect() -> None:
    # f_px = f_eq * (diagonal / width) * width_px / 43.27: 5/4 for any 4:3 sensor.
    expected = 400.0 * 1.25 * 4608 / math.hypot(36.0, 24.0)
    for sensor in (P1000_SENSOR_MM, (3.0, 2.25), (17.3, 12.975), None):
        assert focal_px_from_35mm_equivalent(400.0, sensor, P1000_RESOLUTION) == pytest.approx(
            expected, rel=1e-12
        )


def test_equivalent_with_the_nominal_455_height_is_06_percent_lower() -> None:
    # 6.17 x 4.55: diagonal 7.6663 mm, crop 5.64378, f = 70.8745 mm = 52,931.9 px.
    focal = focal_px_from_35mm_equivalent(400.0, (6.17, 4.55), P1000_RESOLUTION)
    assert focal == pytest.approx(52_931.9, abs=0.1)


def test_fov_synthetic_is_six_degrees() -> None:
    # Paper Sec. 4.2: 6 deg across 4608 px, f = 2304 / tan(3 deg) = 43,963 px.
    focal = 2304 / math.tan(math.radians(3.0))
    assert focal == pytest.approx(43_962.94, abs=0.01)
    assert fov_deg(focal, 4608) == pytest.approx(6.0, abs=1e-12)


def test_paper_fov_used_the_full_frame_width_not_the_diagonal() -> None:
    # Paper Sec. 4.3 quotes 5.16 x 3.44 deg at 400 mm-eq: that is 36 mm / 400 mm and
    # 24 mm / 400 mm in radians (a 3:2 full frame), not the 4:3 image's field.
    assert round(math.degrees(36 / 400), 2) == 5.16
    assert round(math.degrees(24 / 400), 2) == 3.44
    correct = focal_px_from_35mm_equivalent(400.0, P1000_SENSOR_MM, P1000_RESOLUTION)
    assert fov_deg(correct, 4608) == pytest.approx(4.955, abs=1e-3)
    assert fov_deg(correct, 3456) == pytest.approx(3.717, abs=1e-3)
    # The diagonal field is the same as a 400 mm lens's on full frame, by definition.
    assert fov_deg(correct, math.hypot(4608, 3456)) == pytest.approx(
        math.degrees(2 * math.atan(math.hypot(36, 24) / 2 / 400)), rel=1e-12
    )


@pytest.mark.parametrize(
    "call",
    [
        lambda: focal_px_from_mm(0.0, 6.17, 4608),
        lambda: focal_px_from_mm(71.3, -6.17, 4608),
        lambda: focal_px_from_35mm_equivalent(400.0, (6.17, 0.0), P1000_RESOLUTION),
        lambda: fov_deg(0.0, 4608),
    ],
)
def test_conversions_reject_non_positive_input(call: Callable[[], float]) -> None:
    with pytest.raises(ValueError, match="must be > 0"):
        call()


# --------------------------------------------------------------------------- shipped profiles


def test_rigs_folder_ships_the_three_profiles() -> None:
    assert {path.stem for path in SHIPPED} >= {"p1000-tripod", "vehicle-2m", "synthetic"}


@pytest.mark.parametrize("path", SHIPPED, ids=lambda path: path.stem)
def test_shipped_profile_round_trips(path: Path, tmp_path: Path) -> None:
    profile = load_rig(path)
    copy = tmp_path / path.name
    copy.write_text(dump_rig(profile), encoding="utf-8")
    again = load_rig(copy)
    assert again == profile
    assert again.source == copy
    assert dump_rig(again) == dump_rig(profile)


def test_p1000_profile() -> None:
    profile = load_rig(ROOT / "rigs" / "p1000-tripod.yaml")
    assert profile.name == "p1000-tripod"
    assert set(profile.cameras) == {"left", "right", "back"}
    assert profile.focal_px == pytest.approx(53_251.2, abs=0.1)
    assert profile.image_size == (4608, 3456)
    assert profile.cameras["back"].focal_given == ("equivalent_35mm_mm", 400.0)
    assert profile.baseline_lr == Baseline(value_m=2.0, tolerance_m=0.02)
    assert profile.back_offset_m == (0.0, 0.0)
    assert profile.rangefinder is not None and profile.rangefinder.protocol == "manual"
    assert "5.16" in profile.notes
    assert profile.one_camera and profile.geometry().one_camera  # one camera, moved


def test_one_camera_is_a_fact_of_the_rig_checked_against_its_specs(tmp_path: Path) -> None:
    three = _with_cameras(tmp_path, _camera(50_000), _camera(50_000), _camera(50_000))
    assert not load_rig(three).one_camera  # three cameras unless the profile says one
    text = three.read_text()
    path = tmp_path / "one.yaml"
    path.write_text(text + "one_camera: true\n")
    assert load_rig(path).one_camera and "one_camera" in rig_to_dict(load_rig(path))
    path.write_text(text.replace(_camera(50_000), _camera(50_040), 1) + "one_camera: true\n")
    with pytest.raises(InputError, match="one_camera: one camera took the three views"):
        load_rig(path)
    path.write_text(text + "one_camera: yes please\n")
    with pytest.raises(InputError, match="one_camera: must be true"):
        load_rig(path)


def test_synthetic_profile_matches_the_paper_protocol() -> None:
    profile = load_rig(ROOT / "rigs" / "synthetic.yaml")
    assert profile.focal_px == pytest.approx(43_963, abs=0.5)
    assert fov_deg(profile.focal_px, profile.image_size[0]) == pytest.approx(6.0, abs=1e-9)
    assert profile.baseline_lr.value_m == profile.baseline_lb.value_m == 2.0
    assert profile.nominal_range_m == 300.0
    assert profile.back_offset_m == (0.0, 0.3)
    assert profile.cameras["left"].principal_point_px is None


def test_vehicle_profile_converts_real_millimetres() -> None:
    profile = load_rig(ROOT / "rigs" / "vehicle-2m.yaml")
    # 150 mm on 3.45 um pixels: 150 / 0.00345 = 43,478 px (sensor 14.131 mm / 4096 px).
    assert profile.focal_px == pytest.approx(150 * 4096 / 14.131, rel=1e-12)
    assert profile.focal_px == pytest.approx(43_478.9, abs=0.1)
    rangefinder = profile.rangefinder
    assert rangefinder is not None
    assert (rangefinder.port, rangefinder.baud) == ("/dev/ttyUSB0", 115200)
    assert rangefinder.offset_m == (0.10, 0.08, 0.0)


def test_profile_is_frozen() -> None:
    profile = load_rig(ROOT / "rigs" / "synthetic.yaml")
    with pytest.raises(dataclasses.FrozenInstanceError):
        profile.name = "other"  # type: ignore[misc]
    with pytest.raises(TypeError):
        profile.cameras["left"] = profile.cameras["right"]  # type: ignore[index]
    assert hash(profile) == hash(load_rig(ROOT / "rigs" / "synthetic.yaml"))


# --------------------------------------------------------------------------- per-camera specs


def _with_cameras(tmp_path: Path, left: str, right: str, back: str) -> Path:
    text = f"""version: 1
name: three-cameras
cameras:
  left: {left}
  right: {right}
  back: {back}
baselines:
  C_lr: {{value_m: 2.0, tolerance_m: 0.01}}
  C_lb: {{value_m: 2.0, tolerance_m: 0.01}}
"""
    path = tmp_path / "three.yaml"
    path.write_text(text, encoding="utf-8")
    return path


def _camera(focal_px: float, resolution: str = "[4608, 3456]") -> str:
    return (
        f"{{model: cam, resolution: {resolution}, "
        f"focal_length: {{px: {focal_px}, tolerance_fraction: 0.01}}}}"
    )


def test_cameras_within_a_tenth_of_a_percent_share_the_mean_focal(tmp_path: Path) -> None:
    path = _with_cameras(tmp_path, _camera(50_000), _camera(50_040), _camera(50_020))
    profile = load_rig(path)
    assert profile.focal_px == pytest.approx(50_020.0)
    assert profile.cameras["right"] == CameraSpec(
        model="cam",
        sensor_mm=None,
        resolution=(4608, 3456),
        focal_px=50_040.0,
        focal_tolerance=0.01,
        principal_point_px=None,
        focal_given=("px", 50_040.0),
    )


def test_cameras_with_different_focal_lengths_are_refused(tmp_path: Path) -> None:
    path = _with_cameras(tmp_path, _camera(50_000), _camera(50_000), _camera(50_100))
    profile = load_rig(path)
    with pytest.raises(InputError, match=r"three\.yaml: cameras: focal lengths differ by 0\.20 %"):
        _ = profile.focal_px


def test_cameras_with_different_resolutions_are_refused(tmp_path: Path) -> None:
    path = _with_cameras(
        tmp_path, _camera(50_000), _camera(50_000, "[4096, 3072]"), _camera(50_000)
    )
    with pytest.raises(InputError, match="resolutions differ .*right 4096x3072"):
        _ = load_rig(path).image_size


def test_yaml_anchor_and_merge_key_share_a_spec(tmp_path: Path) -> None:
    path = tmp_path / "anchors.yaml"
    path.write_text(
        """version: 1
name: anchors
cameras:
  left: &cam {model: cam A, resolution: [4608, 3456],
              focal_length: {px: 50000, tolerance_fraction: 0.01}}
  right: *cam
  back: {<<: *cam, model: cam B}
baselines:
  C_lr: {value_m: 2.0, tolerance_m: 0.01}
  C_lb: {value_m: 2.0, tolerance_m: 0.01}
""",
        encoding="utf-8",
    )
    profile = load_rig(path)
    assert profile.cameras["back"].model == "cam B"
    assert profile.cameras["back"].focal_px == profile.cameras["left"].focal_px == 50_000.0


# --------------------------------------------------------------------------- invalid profiles


def test_bad_examples_exist() -> None:
    assert len(BAD) >= 20


@pytest.mark.parametrize("path", BAD, ids=lambda path: path.stem)
def test_bad_profile_gives_its_specific_error(path: Path) -> None:
    # Each file's first line is "# error: <the text the message must contain>".
    first = path.read_text(encoding="utf-8").splitlines()[0]
    assert first.startswith("# error: ")
    expected = first.removeprefix("# error: ")
    with pytest.raises(InputError) as caught:
        load_rig(path)
    message = str(caught.value)
    assert message.startswith(f"{path}: ")
    assert expected in message
    assert "\n" not in message


def test_missing_file(tmp_path: Path) -> None:
    with pytest.raises(InputError, match=r"nope\.yaml: no such rig profile"):
        load_rig(tmp_path / "nope.yaml")


def test_cli_reports_a_bad_profile_on_one_line(capsys: pytest.CaptureFixture[str]) -> None:
    path = ROOT / "tests" / "data" / "bad_rigs" / "negative_focal_mm.yaml"
    assert main(["rig", "check", str(path)]) == 2
    captured = capsys.readouterr()
    assert captured.out == ""
    assert captured.err == (
        f"rigkit rig: error: {path}: cameras.left.focal_length.mm: "
        "must be > 0 and <= 5000 mm, got -71.3\n"
    )


def test_a_calibrated_profiles_provenance_reads_back(tmp_path: Path) -> None:
    """Where the scale came from travels with the profile: sessions, their frames' hash,
    targets used, held out and rejected, what changed."""
    from rigkit.rig.provenance import Calibration, CalibrationSource

    profile = load_rig(ROOT / "rigs" / "p1000-tripod.yaml")
    source = CalibrationSource("ridge-0412", "/data/ridge-0412", "ab" * 32, "run-1",
                               "2026:04:12 08:00:00", {"T1": (512.0, 300.5), "7": (1.0, 2.0)},
                               held_out=("T3",), rejected=("T5",))
    record = Calibration("2026-04-13T09:00:00Z", "p1000-tripod", (source,), 301.2,
                         ("C_lb 2.0000 +- 0.0200 m -> 2.0310 +- 0.0040 m",),
                         "leave-one-out: 2/2 targets within 1 %", 0.93, 3)
    path = tmp_path / "cal.yaml"
    path.write_text(dump_rig(dataclasses.replace(profile, calibration=record)))
    assert load_rig(path).calibration == record
