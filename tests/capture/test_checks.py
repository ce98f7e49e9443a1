"""The capture check: EXIF of the three frames against each other and the rig profile."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest

from rigkit.capture.checks import check_capture, size_findings
from rigkit.errors import InputError
from rigkit.imagefile.exif import read_exif
from rigkit.rig import load_rig
from tests.conftest import rig_file

ROOT = Path(__file__).resolve().parents[2]
P1000 = ROOT / "rigs" / "p1000-tripod.yaml"
VEHICLE = ROOT / "rigs" / "vehicle-2m.yaml"

Image = pytest.importorskip("PIL.Image")
IFDRational = pytest.importorskip("PIL.TiffImagePlugin").IFDRational


# --------------------------------------------------------------------------- EXIF capture check


def _frame(path: Path, **changes: Any) -> Path:
    """A tiny image whose EXIF says P1000 at 400 mm-eq, 1/500 s, f/5.6, ISO 200, 4608x3456."""
    tags: dict[str, Any] = {
        "model": "COOLPIX P1000",
        "focal_mm": IFDRational(719, 10),
        "focal_35mm": 400,
        "exposure": IFDRational(1, 500),
        "f_number": IFDRational(56, 10),
        "iso": 200,
        "size": (4608, 3456),
        "time": None,
    }
    tags.update(changes)
    exif = Image.Exif()
    exif[0x010F] = "NIKON"
    exif[0x0110] = tags["model"]
    sub = exif.get_ifd(0x8769)
    for tag, key in (
        (0x920A, "focal_mm"),
        (0xA405, "focal_35mm"),
        (0x829A, "exposure"),
        (0x829D, "f_number"),
        (0x8827, "iso"),
    ):
        if tags[key] is not None:
            sub[tag] = tags[key]
    sub[0xA002], sub[0xA003] = tags["size"]
    if tags["time"] is not None:
        sub[0x9003] = tags["time"]
    Image.new("L", (8, 6)).save(path, exif=exif.tobytes())
    return path


@pytest.mark.parametrize("suffix", [".jpg", ".tif"])
def test_read_exif(tmp_path: Path, suffix: str) -> None:
    info = read_exif(_frame(tmp_path / f"frame{suffix}"))
    assert (info.make, info.model) == ("NIKON", "COOLPIX P1000")
    assert info.focal_length_mm == pytest.approx(71.9)
    assert info.focal_length_35mm_mm == 400.0
    assert info.exposure_time_s == pytest.approx(0.002)
    assert info.f_number == pytest.approx(5.6)
    assert info.iso == 200.0
    assert info.has_exif


def test_read_exif_without_exif(tmp_path: Path) -> None:
    path = tmp_path / "plain.png"
    Image.new("L", (8, 6)).save(path)
    assert not read_exif(path).has_exif


def test_read_exif_missing_file(tmp_path: Path) -> None:
    with pytest.raises(InputError, match=r"gone\.jpg: no such file"):
        read_exif(tmp_path / "gone.jpg")


def test_matching_capture_has_no_findings(tmp_path: Path) -> None:
    frames = [_frame(tmp_path / name) for name in ("L.jpg", "R.jpg", "B.tif")]
    assert check_capture(load_rig(P1000), frames) == []


def test_capture_mismatches_name_frame_and_field(tmp_path: Path) -> None:
    frames = [
        _frame(tmp_path / "L.jpg"),
        _frame(tmp_path / "R.jpg", exposure=IFDRational(1, 250)),
        _frame(tmp_path / "B.jpg", focal_mm=IFDRational(539, 10), focal_35mm=300),
    ]
    findings = check_capture(load_rig(P1000), frames)
    found = {(f.code, f.frame, f.field) for f in findings}
    assert found == {
        ("capture.mismatch", "back", "FocalLength"),
        ("capture.mismatch", "back", "FocalLengthIn35mmFilm"),
        ("capture.mismatch", "right", "ExposureTime"),
        ("capture.focal_vs_profile", "back", "FocalLengthIn35mmFilm"),
    }
    messages = "\n".join(f.message for f in findings)
    assert (
        "right frame (R.jpg): ExposureTime 1/250 s differs from the left frame's 1/500 s"
        in messages
    )
    assert "back frame (B.jpg): FocalLengthIn35mmFilm 300 mm is 39,938 px, -25.0 %" in messages


def test_capture_times_too_far_apart(tmp_path: Path) -> None:
    times = ("2026:11:22 10:00:00", "2026:11:22 10:04:10", "2026:11:22 10:09:30")
    frames = [_frame(tmp_path / f"{i}.jpg", time=t) for i, t in enumerate(times)]
    assert check_capture(load_rig(P1000), frames) == []
    frames[2] = _frame(tmp_path / "late.jpg", time="2026:11:22 11:15:00")
    (finding,) = check_capture(load_rig(P1000), frames)
    assert finding.code == "capture.time_spread"
    assert "frames taken 75 min apart (left 10:00:00, right 10:04:10, back 11:15:00)" in (
        finding.message
    )
    frames[2] = _frame(tmp_path / "bad.jpg", time="yesterday")
    assert [f.code for f in check_capture(load_rig(P1000), frames)] == ["capture.bad_time"]


def test_capture_model_and_missing_fields(tmp_path: Path) -> None:
    frames = [
        _frame(tmp_path / "L.jpg", size=(3456, 4608)),  # an EXIF size is not checked
        _frame(tmp_path / "R.jpg", model="D850"),
        _frame(tmp_path / "B.jpg", iso=None),
    ]
    findings = check_capture(load_rig(P1000), frames)
    assert {(f.code, f.frame) for f in findings} == {
        ("capture.model_vs_profile", "right"),
        ("capture.missing_field", "back"),
    }


def test_sizes_are_the_decoded_ones_not_the_exif_ones(tmp_path: Path) -> None:
    # EXIF claims the profile's 4608x3456 (as a preview's tags may claim anything); the
    # decoded frames are 8x6 and, turned, 6x8: the check quotes what was decoded.
    frames = [_frame(tmp_path / "L.jpg"), _frame(tmp_path / "R.jpg")]
    Image.new("L", (6, 8)).save(tmp_path / "B.png")
    rig = rig_file(tmp_path, (8, 6))
    assert [f.frame for f in size_findings(load_rig(rig), [*frames, tmp_path / "B.png"])] == \
        ["back"]
    (found,) = size_findings(load_rig(rig), [*frames, tmp_path / "B.png"])
    assert "decoded image 6x8 px differs from the profile's 8x6 px (turned to portrait?)" in \
        found.message
    assert len(size_findings(load_rig(P1000), frames + frames[:1])) == 3


def test_capture_focal_in_real_mm_uses_the_sensor_width(tmp_path: Path) -> None:
    # vehicle-2m states f = 150 mm: a frame recording 150 mm matches, 160 mm (+6.7 %) does not.
    frames = [
        _frame(
            tmp_path / f"{name}.jpg", model="cam", focal_mm=mm, focal_35mm=None, size=(4096, 3000)
        )
        for name, mm in (("L", 150), ("R", 150), ("B", 160))
    ]
    findings = check_capture(load_rig(VEHICLE), frames)
    focal = [f for f in findings if f.code == "capture.focal_vs_profile"]
    assert [(f.frame, f.field) for f in focal] == [("back", "FocalLength")]
    assert "+6.7 % off" in focal[0].message


def test_capture_without_exif_and_wrong_count(tmp_path: Path) -> None:
    plain = tmp_path / "plain.png"
    Image.new("L", (8, 6)).save(plain)
    frames = [_frame(tmp_path / "L.jpg"), _frame(tmp_path / "R.jpg"), plain]
    findings = check_capture(load_rig(P1000), frames)
    assert [(f.code, f.frame) for f in findings] == [("capture.no_exif", "back")]
    with pytest.raises(InputError, match="three images"):
        check_capture(load_rig(P1000), frames[:2])
