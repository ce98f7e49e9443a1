"""``rigkit depth`` fed as users feed it: camera RAW files, the wrong rig, swapped
positions, damaged files; and its --help, whose examples must name files that exist."""

from __future__ import annotations

import json
import re
import shlex
from pathlib import Path

import cv2
import numpy as np
import pytest

from rigkit.cli import main
from tests.dngutil import bayer_from_grey, write_camera_dng

ROOT = Path(__file__).resolve().parents[2]
VIEWS = ("left", "right", "back")


@pytest.fixture(scope="module")
def dng_scene(scene_dir: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The shared 960x720 scene's frames written as camera-style DNGs (a 160x120
    preview in IFD 0, the raw mosaic in a SubIFD), as cameras and converters write them."""
    out = tmp_path_factory.mktemp("dng")
    for view in VIEWS:
        grey = cv2.imread(str(scene_dir / f"{view}.png"), cv2.IMREAD_GRAYSCALE)
        write_camera_dng(out / f"{view}.dng", bayer_from_grey(grey))
    return out


def _depth(folder: Path, suffix: str, out: Path, *flags: str) -> int:
    frames = [str(folder / f"{v}.{suffix}") for v in VIEWS]
    return main(["depth", *frames, "--out", str(out), "--quiet", *flags])


def test_raw_frames_give_the_depth_of_their_pngs_at_full_size(scene_depth, dng_scene, truth,
                                                                tmp_path) -> None:
    # The PNGs' depth: the shared run of the same command with the same flags (its
    # --preview only adds PNG files; tests/commands/conftest.py).
    code, png_folder, _ = scene_depth
    assert code == 0
    flags = ("--focal-px", str(truth.focal_px), "--baseline-lr", "2", "--baseline-lb", "2")
    assert _depth(dng_scene, "dng", tmp_path / "dng.npy", *flags) == 0
    png, dng = np.load(png_folder / "d.npy"), np.load(tmp_path / "dng.npy")
    assert dng.shape == png.shape == (720, 960)  # not the 120x160 preview OpenCV reads
    both = np.isfinite(png) & np.isfinite(dng)
    assert both.mean() > 0.7
    # The DNGs went through a linear decode and the RAW tone curve, not the PNGs' own:
    # the depths agree to 0.53 % (median), 0.9 % (90th percentile) here. The median is
    # the two runs' offsets apart: each fits the views' principal points (30 px off
    # the centre at 960 px) from its own tracks, and at 960 px the offset is good to
    # ~1 % (tests/pipeline/test_pipeline.py); a preview's depth would be far off.
    change = np.abs(dng[both] / png[both] - 1)
    assert np.median(change) < 0.01 and np.percentile(change, 90) < 0.03
    meta = json.loads((tmp_path / "dng.json").read_text())
    assert meta["image_size_px"] == [960, 720]


def test_swapped_right_and_back_are_refused(scene_dir, truth, tmp_path, capsys) -> None:
    # Before: exit 0, a median depth of 9545 m and only a +-44 % warning.
    frames = [str(scene_dir / f"{v}.png") for v in ("left", "back", "right")]
    args = ["depth", *frames, "--out", str(tmp_path / "d.npy"), "--quiet", "--focal-px",
            str(truth.focal_px), "--baseline-lr", "2", "--baseline-lb", "2"]
    assert main(args) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "were right and back swapped?" in err
    assert not list(tmp_path.iterdir())


def test_a_damaged_raw_file_is_one_line_naming_it(dng_scene, tmp_path, capfd) -> None:
    data = (dng_scene / "back.dng").read_bytes()
    (tmp_path / "back.dng").write_bytes(data[: len(data) // 2])
    frames = [str(dng_scene / "left.dng"), str(dng_scene / "right.dng"), str(tmp_path / "back.dng")]
    assert main(["depth", *frames, "--out", str(tmp_path / "d.npy"), "--quiet",
                 "--focal-px", "9159", "--baseline-lr", "2", "--baseline-lb", "2"]) == 2
    err = capfd.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "back.dng: LibRaw cannot read its data" in err
    assert not (tmp_path / "d.npy").exists()


def test_an_unwritable_output_is_refused_before_any_work(scene_dir, tmp_path, capsys) -> None:
    (tmp_path / "out.npy").mkdir()
    args = [str(scene_dir / f"{v}.png") for v in VIEWS]
    assert main(["depth", *args, "--out", str(tmp_path / "out.npy"), "--focal-px", "9159",
                 "--baseline-lr", "2", "--baseline-lb", "2", "--quiet"]) == 2
    assert "out.npy is a folder, not a file rigkit may write" in capsys.readouterr().err


def test_help_examples_name_files_that_exist(capsys, monkeypatch) -> None:
    monkeypatch.chdir(ROOT)
    with pytest.raises(SystemExit):
        main(["depth", "--help"])
    text = capsys.readouterr().out.replace("\\\n", "")
    commands = [shlex.split(line.strip()) for line in text.splitlines()
                if line.strip().startswith("rigkit depth ")]
    assert commands
    named = {arg for command in commands for word in command for arg in word.split(",")
             if re.match(r"(capture|rigs)/", arg)}
    assert named and all((ROOT / name).is_file() for name in named), named


def _depth_args(*flags: str) -> object:
    from rigkit.cli import build_parser

    return build_parser().parse_args(["depth", "l.png", "r.png", "b.png", "--out", "d.npy",
                                      *flags])


def test_rig_flags_go_into_the_profile_which_is_checked_once(tmp_path: Path) -> None:
    from rigkit.commands.depth_run import flags_profile, rig_profile
    from rigkit.errors import InputError

    profile = ROOT / "rigs" / "p1000-tripod.yaml"
    rig = rig_profile(_depth_args("--rig", str(profile), "--focal-px", "53000",
                                 "--baseline-lb", "2.1"))
    assert rig.focal_px == 53000.0 and rig.baseline_lb.value_m == 2.1
    assert rig.baseline_lb.tolerance_m == 0.02  # the profile's tolerance is kept
    assert rig.cameras["left"].focal_tolerance == 0.01
    # One camera moved between the positions: a fact of the rig, from the flag too.
    flags = ("--focal-px", "53000", "--baseline-lr", "2", "--baseline-lb", "2")
    assert not flags_profile(_depth_args(*flags), (640, 480)).geometry().one_camera
    assert flags_profile(_depth_args(*flags, "--one-camera"), (640, 480)).geometry().one_camera
    for text, named in (("- a list\n", "must be a mapping"),
                        ("version: 1\nname: x\ncamera: {}\n", "baselines")):
        bad = tmp_path / "bad.yaml"
        bad.write_text(text)
        with pytest.raises(InputError, match=named) as caught:
            rig_profile(_depth_args("--rig", str(bad), "--focal-px", "53000"))
        assert str(bad) in str(caught.value) and "\n" not in str(caught.value)
