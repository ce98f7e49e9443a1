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


def test_lensfun_profile_by_camera_and_focal_length(tmp_path) -> None:
    # The paper's camera at ~400 mm-equivalent (71.9 mm real): lensfun's profile bends
    # the image by a few percent between the centre and the corner.
    path = _profile(tmp_path, extra_camera="  distortion: {lensfun: Coolpix P1000, focal_mm: 71.9}")
    rig = load_rig(path)
    spec = rig.cameras["left"].lens_profile
    assert spec is not None and "P1000" in spec.lens and spec.focal_mm == 71.9
    assert rig.distortion == spec.distortion and rig.distortion[0] > 0
    assert 0.95 < spec.centre_scale < 1.0 and spec.fit_error_px < 3.0
    again = tmp_path / "again.yaml"
    again.write_text(dump_rig(rig))
    assert "lensfun" in again.read_text()
    assert load_rig(again).distortion == rig.distortion


def test_lensfun_conversion_follows_lensfuns_own_map() -> None:
    import lensfunpy
    import numpy as np

    from rigkit.geometry import distort
    from rigkit.rig.lensfun import lensfun_profile

    w, h, f = 4608, 3456, 53251.0
    spec = lensfun_profile("Coolpix P1000", 71.9, (w, h), f)
    db = lensfunpy.Database()
    cam = next(c for c in db.cameras if c.model == "Coolpix P1000")
    lens = db.find_lenses(cam, loose_search=True)[0]
    mod = lensfunpy.Modifier(lens, cam.crop_factor, w, h)
    mod.initialize(71.9, 4.0, 1000.0)
    # lensfun: corrected pixel -> recorded pixel, on a row a third of the way down.
    y = h // 3
    recorded = mod.apply_geometry_distortion(0, y, w, 1)[0].astype(np.float64)
    c = np.array([(w - 1) / 2, (h - 1) / 2])
    # rigkit's model: the corrected pixel is ideal at lensfun's scale, s at the centre.
    ideal = (np.stack([np.arange(w), np.full(w, y)], axis=1) - c) * spec.centre_scale / f
    xd, yd = distort(ideal[:, 0], ideal[:, 1], spec.distortion)
    ours = np.stack([xd, yd], axis=1) * f + c
    assert np.abs(ours - recorded).max() < spec.fit_error_px + 0.05
    assert np.abs(ours - recorded).max() < 3.0


@pytest.mark.parametrize(
    ("distortion", "message"),
    [
        ("{lensfun: Koolpix P1000, focal_mm: 71.9}", r"no camera 'Koolpix P1000'; did you mean"),
        ("{lensfun: Coolpix P1000, focal_mm: 900}", r"covers 4.3-539 mm, not 900 mm"),
        ("{lensfun: Coolpix P1000}", r"distortion\.focal_mm: missing"),
        ("{lensfun: Canon EOS 5D, focal_mm: 50}", r"name the lens"),
    ],
)
def test_lensfun_lookup_errors_name_the_key(tmp_path, distortion, message) -> None:
    with pytest.raises(InputError, match=message):
        load_rig(_profile(tmp_path, extra_camera=f"  distortion: {distortion}"))
