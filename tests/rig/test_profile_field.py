"""Rig profiles: the lens distortion and the pipeline settings a profile can set."""

from __future__ import annotations

from pathlib import Path

import pytest

from rigkit.errors import InputError
from rigkit.rig import load_rig
from rigkit.rig.profile import dump_rig

BASE = """version: 1
name: test
camera:
  model: test camera
  resolution: [4608, 3456]
  focal_length: {px: 43963, tolerance_fraction: 0.01}
{extra_camera}
baselines:
  C_lr: {{value_m: 2.0, tolerance_m: 0.01}}
  C_lb: {{value_m: 2.0, tolerance_m: 0.01}}
{extra}
"""


def _profile(tmp_path: Path, extra_camera: str = "", extra: str = "") -> Path:
    path = tmp_path / "rig.yaml"
    text = BASE.replace("{extra_camera}", extra_camera).replace("{extra}", extra)
    path.write_text(text.replace("{{", "{").replace("}}", "}"))
    return path


def test_distortion_and_settings_reach_the_pipeline(tmp_path) -> None:
    path = _profile(
        tmp_path,
        extra_camera="  distortion: {k1: 0.47, p2: -0.001}",
        extra="pipeline: {min_texture: 4, n_points: 5000}",
    )
    rig = load_rig(path)
    assert rig.distortion == (0.47, 0.0, 0.0, -0.001, 0.0)
    assert rig.geometry().distortion == (0.47, 0.0, 0.0, -0.001, 0.0)
    settings = rig.pipeline_settings()
    assert settings.min_texture == 4.0 and settings.n_points == 5000
    assert isinstance(settings.n_points, int)
    # written back as read
    again = tmp_path / "again.yaml"
    again.write_text(dump_rig(rig))
    assert load_rig(again).pipeline_settings() == settings
    assert load_rig(again).distortion == rig.distortion


def test_no_distortion_and_defaults_when_absent(tmp_path) -> None:
    rig = load_rig(_profile(tmp_path))
    assert rig.distortion == (0.0,) * 5
    assert rig.pipeline_settings().stereo_scale == 0.5


@pytest.mark.parametrize(
    ("extra_camera", "extra", "message"),
    [
        ("  distortion: {k4: 0.1}", "", r"camera\.distortion\.k4: unknown key"),
        ("  distortion: {k1: fast}", "", r"camera\.distortion\.k1: must be a number"),
        ("", "pipeline: {min_textures: 4}", r"pipeline\.min_textures: unknown key.*min_texture"),
        ("", "pipeline: {n_points: 2.5}", r"pipeline\.n_points: must be a whole number"),
        ("", "pipeline: {stereo_scale: 3}", r"pipeline: stereo_scale must be in"),
    ],
)
def test_bad_values_name_the_key(tmp_path, extra_camera, extra, message) -> None:
    with pytest.raises(InputError, match=message):
        load_rig(_profile(tmp_path, extra_camera, extra))
