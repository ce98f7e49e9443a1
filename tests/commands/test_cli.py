"""The CLI as a user drives it: outputs, one-line errors, exit codes."""

from __future__ import annotations

import json
import re
from pathlib import Path

import cv2
import numpy as np
import pytest

from rigkit.cli import main
from tests.conftest import rig_file


def _depth_args(scene_dir, out, *extra):
    imgs = [str(scene_dir / f"{v}.png") for v in ("left", "right", "back")]
    return ["depth", *imgs, "--out", str(out), "--quiet", *extra]


def test_depth_writes_depth_sigma_sidecar_and_previews(scene_depth, truth):
    # `rigkit depth` with the focal length and baselines as flags and --preview, run once
    # for this test and test_depth_inputs.py (tests/commands/conftest.py).
    code, folder, printed = scene_depth
    assert code == 0
    depth = np.load(folder / "d.npy")
    assert depth.shape == truth.depth("left").shape and depth.dtype == np.float32
    assert np.load(folder / "d.sigma.npy").shape == depth.shape
    meta = json.loads((folder / "d.json").read_text())
    assert meta["matches"]["left_right"] > 100 and "stereo" in meta["timings_s"]
    assert cv2.imread(str(folder / "d.png")) is not None
    assert "wrote" in printed
    # What rigkit export needs: the left image's grey values and the intrinsics.
    grey = cv2.imread(str(folder / "d.grey.png"), cv2.IMREAD_UNCHANGED)
    assert grey.shape == depth.shape and grey.dtype == np.uint8
    # The left view as the run took it: its lens fit's centre (the scene's principal
    # point lies off the image centre (479.5, 359.5); the fit moves towards it).
    camera, centre = meta["left_camera_px"], meta["lens_fit"]["centres_px"]["left"]
    assert camera["f"] == truth.focal_px
    assert camera["cx"] - 479.5 == pytest.approx(centre[0], abs=0.006)
    assert camera["cy"] - 359.5 == pytest.approx(centre[1], abs=0.006)
    true_cx, true_cy = truth.cameras["left"].K[0, 2], truth.cameras["left"].K[1, 2]
    assert abs(camera["cx"] - true_cx) < abs(479.5 - true_cx)
    assert abs(camera["cy"] - true_cy) < abs(359.5 - true_cy)
    # What each depth rests on: matched (1) or filled (2) wherever there is one.
    flags_png = np.load(folder / "d.flags.npy")  # data, not a picture: .npy
    assert flags_png.shape == depth.shape and flags_png.dtype == np.uint8
    known = np.isfinite(depth)
    assert np.all(flags_png[known] & 3) and not np.any(flags_png[~known] & 3)


def test_depth_reads_the_rig_profile(scene_dir, truth, tmp_path):
    # A profile for the frames' size gives f and both baselines.
    out = tmp_path / "d.npy"
    rig = rig_file(tmp_path, (960, 720))
    assert main(_depth_args(scene_dir, out, "--rig", str(rig))) == 0 and out.is_file()
    meta = json.loads((tmp_path / "d.json").read_text())
    assert meta["rig"]["focal_px"] == pytest.approx(truth.focal_px)


def test_frames_of_another_size_than_the_profile_are_refused(scene_dir, tmp_path, capsys):
    # rigs/synthetic.yaml is for 4608x3456 frames; these are 960x720: refused before any
    # depth is computed, whatever focal length is given (it was 289.7 m for 302.4 m).
    out = tmp_path / "d.npy"
    args = _depth_args(scene_dir, out, "--rig", "rigs/synthetic.yaml", "--focal-px", "9159")
    assert main(args) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1
    assert "left.png: 960x720 px, but the rig profile synthetic is for 4608x3456 px" in err
    assert not out.exists()


@pytest.mark.parametrize(
    "change, message",
    [
        (lambda a, t: a.__setitem__(1, str(t / "nope.png")), "no such file"),
        (lambda a, t: a.__setitem__(a.index("--out") + 1, str(t / "d.txt")), ".npy"),
        (lambda a, t: a.extend(["--focal-px", "0"]), "--focal-px 0: must be a positive"),
    ],
)
def test_bad_input_is_one_line_and_exit_2(scene_dir, tmp_path, capsys, change, message):
    args = _depth_args(scene_dir, tmp_path / "d.npy", "--baseline-lr", "2", "--baseline-lb", "2")
    if message != "--focal-px 0: must be a positive":
        args += ["--focal-px", "9000"]
    change(args, tmp_path)
    assert main(args) == 2
    err = capsys.readouterr().err.strip()
    assert message in err and len(err.splitlines()) == 1 and err.startswith("rigkit depth: error")
    assert not (tmp_path / "d.npy").exists()


def test_mismatched_sizes_leave_no_output(scene_dir, tmp_path, capsys):
    small = tmp_path / "right.png"
    img = cv2.imread(str(scene_dir / "right.png"), cv2.IMREAD_UNCHANGED)
    cv2.imwrite(str(small), img[:-4])
    args = _depth_args(scene_dir, tmp_path / "d.npy", "--focal-px", "9000")
    args[2] = str(small)
    assert main([*args, "--baseline-lr", "2", "--baseline-lb", "2"]) == 2
    assert "right.png: 960x716 px, but the left frame" in capsys.readouterr().err
    assert list(tmp_path.iterdir()) == [small]


def test_help_lists_every_command(capsys):
    with pytest.raises(SystemExit):
        main(["--help"])
    out = capsys.readouterr().out
    for cmd in ("depth", "synth", "eval", "rig", "rangefinder"):
        assert cmd in out


@pytest.fixture(scope="module")
def burst_dir(tmp_path_factory):
    """A 640x480 scene rendered as bursts of two frames per position in still air."""
    from dataclasses import replace

    from rigkit.synth import SynthParams, generate_scene, write_scene

    out = tmp_path_factory.mktemp("burst") / "scene"
    params = replace(SynthParams(width=640, height=480), burst=2)
    write_scene(generate_scene(params, seed=4), out)
    return out


def test_depth_takes_bursts_and_a_distortion(burst_dir, tmp_path, capsys):
    # A burst of two frames per position and a zero distortion; both are recorded in
    # the sidecar.
    from rigkit.synth import load_scene

    truth = load_scene(burst_dir)
    burst = [",".join(str(p) for p in truth.frame_paths(v)) for v in ("left", "right", "back")]
    out = tmp_path / "d.npy"
    flags = ["--focal-px", str(truth.focal_px), "--baseline-lr", "2", "--baseline-lb", "2"]
    args = ["depth", *burst, "--out", str(out), "--quiet", *flags, "--distortion", "0,0"]
    assert main(args) == 0
    meta = json.loads((tmp_path / "d.json").read_text())
    assert len(meta["frames"]["left"]) == 2 and meta["burst_length"] == 2
    assert meta["rig"]["distortion"] == [0.0] * 5
    assert meta["settings"]["min_texture"] == 3.0
    # Fitted from the views by default: the lens the depth used is the fitted one.
    assert meta["lens_fit"]["start_k1_k2_p1_p2_k3"] == [0.0] * 5
    assert meta["distortion_k1_k2_p1_p2_k3"] == meta["lens_fit"]["k1_k2_p1_p2_k3"]
    # Still air between the frames, so no burst is too short.
    assert meta["shimmer"]["frames"] == "left frames 1 and 2"
    assert meta["shimmer"]["rms_px"] < 0.03
    assert "this capture has" not in capsys.readouterr().err  # no burst warning


def test_depth_with_a_lensfun_profile_held_fixed(scene_dir, truth, tmp_path):
    # The paper's camera's profile on a scene rendered without distortion: held fixed,
    # the depth goes through exactly that lens, and the sidecar says so.
    out = tmp_path / "d.npy"
    args = _depth_args(scene_dir, out, "--focal-px", str(truth.focal_px), "--baseline-lr",
                       "2", "--baseline-lb", "2", "--lensfun", "Coolpix P1000:71.9",
                       "--fixed-lens")
    assert main(args) == 0
    meta = json.loads((tmp_path / "d.json").read_text())
    assert meta["lens_fit"] is None and meta["settings"]["distortion_terms"] == 0
    assert meta["distortion_k1_k2_p1_p2_k3"][0] > 0
    assert meta["rig"]["distortion"] == meta["distortion_k1_k2_p1_p2_k3"]


@pytest.mark.parametrize(
    "value, message",
    [("Coolpix P1000", "expected CAMERA:FOCAL_MM"), ("Koolpix Q1:50", "lensfun has no camera")],
)
def test_bad_lensfun_flag_is_one_line(scene_dir, tmp_path, capsys, value, message):
    args = _depth_args(scene_dir, tmp_path / "d.npy", "--focal-px", "9000",
                       "--baseline-lr", "2", "--baseline-lb", "2", "--lensfun", value)
    assert main(args) == 2
    err = capsys.readouterr().err.strip()
    assert message in err and len(err.splitlines()) == 1
    assert not list(tmp_path.iterdir())


@pytest.mark.parametrize(
    "position, message",
    [(2, "is the same file as .*left.png, given for left and right"),
     (3, "is the same file as .*left.png, given for left and back")],
)
def test_the_same_frame_twice_is_refused_with_no_output(
    scene_dir, truth, tmp_path, capsys, position, message
):
    args = _depth_args(scene_dir, tmp_path / "d.npy", "--focal-px", str(truth.focal_px),
                       "--baseline-lr", "2", "--baseline-lb", "2")
    args[position] = args[1]
    assert main(args) == 2
    err = capsys.readouterr().err.strip()
    assert re.search(message, err) and len(err.splitlines()) == 1
    assert not list(tmp_path.iterdir())


def test_bad_distortion_flag_is_one_line(scene_dir, tmp_path, capsys):
    args = _depth_args(scene_dir, tmp_path / "d.npy", "--focal-px", "9000",
                       "--baseline-lr", "2", "--baseline-lb", "2", "--distortion", "0.1,0.2,0.3")
    assert main(args) == 2
    assert "--distortion '0.1,0.2,0.3': distortion takes 1, 2, 4 or 5" in capsys.readouterr().err


def test_synth_field_writes_a_burst_with_sky(tmp_path):
    out = tmp_path / "f"
    args = ["synth", str(out), "--seed", "2", "--width", "320", "--height", "240", "--field",
            "--burst", "2", "--quiet"]
    assert main(args) == 0
    assert (out / "left-2.png").is_file() and (out / "back-2.png").is_file()
    assert np.isnan(np.load(out / "ground_truth" / "depth_left.npy")).any()


def test_synth_world_flags_reach_the_scene_and_eval_splits_by_them(tmp_path, capsys):
    from rigkit.synth import load_scene

    out = tmp_path / "town"
    args = ["synth", str(out), "--seed", "4", "--width", "320", "--height", "240",
            "--movers", "3", "--shadows", "1", "--shadow-drift", "5", "--facades", "2",
            "--shimmer", "0.2", "--shimmer-spectrum", "vonkarman", "--shimmer-outer", "300",
            "--quiet"]
    assert main(args) == 0
    p = load_scene(out).params
    assert (p.n_movers, p.n_shadows, p.shadow_drift_m, p.n_facades) == (3, 1, 5.0, 2)
    assert (p.shimmer_px, p.shimmer_spectrum, p.shimmer_outer_px) == (0.2, "vonkarman", 300.0)
    depth_dir = tmp_path / "depth"
    depth_dir.mkdir()
    np.save(depth_dir / "town.npy", np.load(out / "ground_truth" / "depth_left.npy"))
    capsys.readouterr()
    assert main(["eval", str(out), "--depth-dir", str(depth_dir)]) == 0
    assert "where the world moves" in capsys.readouterr().out


def test_synth_and_eval_help_show_single_percent_signs(capsys):
    from rigkit.commands.synth import SHIMMER_SPECTRA
    from rigkit.synth.shimmer import SPECTRA

    assert SHIMMER_SPECTRA == SPECTRA  # the flag offers what the generator has
    for cmd in ("synth", "eval"):
        with pytest.raises(SystemExit):
            main([cmd, "--help"])
        out = capsys.readouterr().out
        assert "%" in out and "%%" not in out, cmd


def test_ctrl_c_while_the_commands_load_is_one_line(monkeypatch, capsys) -> None:
    import importlib

    from rigkit.cli import main

    def interrupted(name: str, *args: object) -> object:
        raise KeyboardInterrupt

    monkeypatch.setattr(importlib, "import_module", interrupted)
    assert main(["--help"]) == 130
    assert capsys.readouterr().err == "rigkit: interrupted\n"


@pytest.mark.slow
def test_the_bundled_example_meets_its_goal(tmp_path: Path, capsys) -> None:
    """What scripts/example.sh ends with: `rigkit eval --goal capture/example` after
    processing it (here in a copy)."""
    import shutil

    from rigkit.cli import main

    example = Path(__file__).resolve().parents[2] / "capture" / "example"
    session = tmp_path / "example"
    shutil.copytree(example, session, ignore=shutil.ignore_patterns(
        "results", "derived", "comparisons.csv", "history.log", ".*"))
    assert main(["process", str(session), "--quiet"]) == 0
    capsys.readouterr()
    assert main(["eval", "--goal", str(session)]) == 0
    assert "example: goal met" in capsys.readouterr().out


@pytest.mark.parametrize("argv, said", [
    (["dpeth"], "rigkit: error: argument COMMAND: invalid choice: 'dpeth'"),
    (["depth", "a", "b", "c", "--focal-px", "nan"],
     "rigkit depth: error: argument --focal-px: must be a finite number, got nan"),
    (["rig", "check", "rigs/synthetic.yaml", "--shimmer-px", "1e300"],
     "argument --shimmer-px: must be >= 0 and <= 1000 px, got 1e300"),
    (["rig", "check", "rigs/synthetic.yaml", "--offset-error-px", "1e300"],
     "argument --offset-error-px: must be >= 0 and <= 1000 px, got 1e300"),
    (["rig", "check", "rigs/synthetic.yaml", "--range", "1e-300"],
     "argument --range: must be >= 1 and <= 100000 m, got 1e-300"),
    (["session", "show"], "the following arguments are required: session"),
])
def test_a_mistaken_argument_is_one_line(argv, said, capsys) -> None:
    """Before: argparse printed the command's whole usage (4-21 lines) above the error,
    and budgets of 1e300 px were tracebacks (OverflowError) in rig check."""
    with pytest.raises(SystemExit) as caught:
        main(argv)
    assert caught.value.code == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1 and said in err, err
    assert err.rstrip().endswith("--help)")


@pytest.mark.parametrize("flags, said", [
    (["--seed", "-1"], "synth seed -1 is out of range: a whole number from 0 to 4294967295"),
    (["--noise", "1e300"], "synth parameter noise_dn=1e+300 is out of range"),
    (["--distance", "1e300"], "synth parameter distance_m=1e+300 is out of range"),
    (["--max-pp-offset", "1e9"], "synth parameter max_pp_offset_px=1000000000.0 is out of range"),
])
def test_synth_names_a_number_it_cannot_render(flags, said, tmp_path, capsys) -> None:
    """Before: tracebacks (numpy's SeedSequence, OverflowError in the exposure), or a
    scene whose ground truth was all NaN, exit 0."""
    out = tmp_path / "scene"
    assert main(["synth", str(out), "--width", "128", "--height", "96", *flags]) == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1 and said in err, err
    assert not out.exists()


@pytest.mark.parametrize("focal, fov", [("1e-300", "180"), ("100", "156"), ("1e7", "0.0055")])
def test_a_focal_length_no_telephoto_has_is_named(scene_dir, tmp_path, capsys, focal, fov):
    """Before: --focal-px 1e-300 was an OverflowError traceback, 1e-100 blamed the frames
    (right and back swapped?), and 1e7 on a 1152-px frame wrote depth with an offset of
    40 image widths (the scene is 960 px wide)."""
    frames = [str(scene_dir / f"{view}.png") for view in ("left", "right", "back")]
    assert main(["depth", *frames, "--focal-px", focal, "--baseline-lr", "2",
                 "--baseline-lb", "2", "--out", str(tmp_path / "d.npy")]) == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1 and f"field of view of {fov} deg" in err, err
    assert not (tmp_path / "d.npy").exists()


def test_a_frame_whose_name_holds_a_comma_is_one_frame(tmp_path, monkeypatch) -> None:
    """Before: 'a,b.png' was split as a burst of two missing files, and the error named
    a fragment of the name the user gave."""
    from rigkit.commands.depth import _frames

    monkeypatch.chdir(tmp_path)
    (tmp_path / "a,b.png").write_bytes(b"")
    assert _frames("a,b.png") == [Path("a,b.png")]
    assert _frames("x.png,y.png") == [Path("x.png"), Path("y.png")]  # a burst
    assert _frames("x.png") == [Path("x.png")]
