"""A command never writes over what it reads, nor over files it did not make: outputs
named after an input, a profile written into a session, a table written onto a scene's
own files, a rendering into someone's folder. Each is refused in one line before any
work, exit status 2, and every input keeps its bytes (the rule for outputs,
rigkit.core.outputs; every output option against every forbidden place:
tests/commands/test_outputs.py)."""

from __future__ import annotations

import hashlib
import shutil
from pathlib import Path

import pytest

from rigkit.cli import main
from rigkit.core.outputs import LEDGER
from rigkit.synth import SceneTruth
from tests.conftest import copy_session


def _digests(*paths: Path) -> dict[Path, str]:
    return {p: hashlib.sha256(p.read_bytes()).hexdigest() for p in paths}


@pytest.fixture
def frames(scene_dir: Path, tmp_path: Path) -> list[Path]:
    """A private copy of the shared scene's three PNGs."""
    out = []
    for view in ("left", "right", "back"):
        out.append(tmp_path / f"{view}.png")
        shutil.copy(scene_dir / f"{view}.png", out[-1])
    return out


def _depth(frames: list[Path], truth: SceneTruth, out: Path, *more: str) -> int:
    return main(["depth", *map(str, frames), "--out", str(out), "--quiet", "--focal-px",
                 str(truth.focal_px), "--baseline-lr", "2", "--baseline-lb", "2", *more])


@pytest.mark.parametrize("out, more", [
    ("left.npy", ["--preview"]),   # its preview would be left.png
    ("back.npy", ["--preview"]),
    ("right.grey.npy", []),        # not a preview: its grey image would be right.grey.png
])
def test_depth_outputs_named_after_an_input_are_refused(
    frames: list[Path], truth: SceneTruth, tmp_path: Path, capsys: pytest.CaptureFixture[str],
    out: str, more: list[str],
) -> None:
    if out == "right.grey.npy":  # an input whose name an output shares
        frames[1] = frames[1].rename(tmp_path / "right.grey.grey.png")
    before = _digests(*frames)
    assert _depth(frames, truth, tmp_path / out, *more) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "was not written by rigkit" in err
    assert _digests(*frames) == before
    assert not (tmp_path / out).exists()


def test_an_output_of_rigkit_read_as_an_input_is_kept(
    frames: list[Path], truth: SceneTruth, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A file rigkit wrote may be replaced by the next run, but not while it is read: the
    grey image of one run given as the left frame of the next, to the same --out."""
    assert _depth(frames, truth, tmp_path / "d.npy") == 0
    capsys.readouterr()
    grey = tmp_path / "d.grey.png"
    before = _digests(grey)
    assert _depth([grey, *frames[1:]], truth, tmp_path / "d.npy") == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "would replace the input" in err
    assert _digests(grey) == before


def test_an_input_reached_through_a_link_is_kept(
    frames: list[Path], truth: SceneTruth, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """The left frame given by a link elsewhere: the output named after the file the
    link leads to would destroy it."""
    shots = tmp_path / "shots"
    shots.mkdir()
    linked = shots / "l.png"
    linked.symlink_to(frames[0])
    before = _digests(frames[0])
    assert _depth([linked, *frames[1:]], truth, tmp_path / "left.npy", "--preview") == 2
    assert "was not written by rigkit" in capsys.readouterr().err
    assert _digests(frames[0]) == before


def test_an_output_that_is_a_link_is_refused(
    frames: list[Path], truth: SceneTruth, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """rigkit writes through no link, nor replaces one: the link and the frame it points
    to stay as they are."""
    out = tmp_path / "out"
    out.mkdir()
    (out / "d.grey.png").symlink_to(frames[0])
    before = _digests(*frames)
    assert _depth(frames, truth, out / "d.npy") == 2
    assert "d.grey.png is a symbolic link" in capsys.readouterr().err
    assert (out / "d.grey.png").is_symlink() and not (out / "d.npy").exists()
    assert _digests(*frames) == before


def test_eval_csv_onto_the_scene_is_refused(scene_dir: Path, scene_depth: tuple[int, Path, str],
                                           tmp_path: Path, capsys: pytest.CaptureFixture[str]
                                           ) -> None:
    scene = tmp_path / scene_dir.name
    shutil.copytree(scene_dir, scene)
    estimates = tmp_path / "est"
    estimates.mkdir()
    shutil.copy(scene_depth[1] / "d.npy", estimates / f"{scene.name}.npy")
    kept = _digests(*[p for p in scene.rglob("*") if p.is_file() and p.name != LEDGER],
                    estimates / f"{scene.name}.npy")
    for csv in (scene / "scene.yaml", scene / "ground_truth" / "depth_left.npy",
                estimates / f"{scene.name}.npy"):
        assert main(["eval", str(scene), "--depth-dir", str(estimates), "--csv", str(csv)]) == 2
        err = capsys.readouterr().err
        assert "was not written by rigkit" in err and len(err.splitlines()) == 1
    named = scene / "ground_truth" / "notes.csv"
    named.write_text("kept\n")  # a scene folder's files are kept, read or not
    assert main(["eval", str(scene), "--depth-dir", str(estimates), "--csv", str(named)]) == 2
    assert "was not written by rigkit" in capsys.readouterr().err
    assert main(["eval", str(scene), "--depth-dir", str(estimates), "--csv",
                 str(tmp_path / "eval.txt")]) == 2
    assert "expected a .csv file name" in capsys.readouterr().err
    assert named.read_text() == "kept\n"
    table = scene / "eval.csv"  # a new file there is no input
    assert main(["eval", str(scene), "--depth-dir", str(estimates), "--csv", str(table)]) == 0
    assert table.read_text().startswith("scene,")
    assert _digests(*kept) == kept


def test_rig_calibrate_writes_no_profile_into_a_session(
    processed_small: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    session = copy_session(processed_small, tmp_path)
    before = _digests(*[p for p in session.rglob("*") if p.is_file()])
    for out in (session / "session.yaml", session / "calibrated.yaml",
                session / "raw" / "rig.yml"):
        assert main(["rig", "calibrate", str(session), "--out", str(out), "--force"]) == 2
        err = capsys.readouterr().err
        assert ("kept as captured" in err or "which only rigkit's session commands write"
                in err) and len(err.strip().splitlines()) == 1
    assert main(["rig", "calibrate", str(session), "--out", str(tmp_path / "x.txt")]) == 2
    assert "expected a .yaml file name" in capsys.readouterr().err
    assert _digests(*before) == before


def _render(out: Path, *more: str) -> int:
    return main(["synth", str(out), "--width", "160", "--height", "120", "--quiet", *more])


def test_synth_renders_over_nothing_it_did_not_make(tmp_path: Path,
                                                    capsys: pytest.CaptureFixture[str]) -> None:
    mine = tmp_path / "mine"
    mine.mkdir()
    (mine / "left.png").write_bytes(b"a photo")
    (mine / "scene.yaml").write_text("mine: 1\n")
    assert _render(mine) == 2
    assert "no scene rendered by rigkit synth" in capsys.readouterr().err
    assert (mine / "left.png").read_bytes() == b"a photo"
    assert sorted(p.name for p in mine.iterdir()) == ["left.png", "scene.yaml"]

    scene = tmp_path / "scene"
    assert _render(scene, "--seed", "1") == 0
    first = (scene / "left.png").read_bytes()
    assert _render(scene, "--seed", "2") == 0  # a scene of its own: rendered again
    assert (scene / "left.png").read_bytes() != first
    (scene / "notes.txt").write_text("mine\n")
    assert _render(scene, "--seed", "3") == 2
    capsys.readouterr()

    session = tmp_path / "session"
    assert _render(session, "--session", "--targets", "2") == 0
    kept = _digests(*[p for p in session.rglob("*") if p.is_file()])
    for more in (["--session"], []):
        assert _render(session, "--seed", "4", *more) == 2
        assert "new or empty folder" in capsys.readouterr().err
    assert _digests(*kept) == kept


@pytest.mark.parametrize("flag", ["--noise", "--distance", "--fov"])
@pytest.mark.parametrize("value", ["nan", "inf", "-inf"])
def test_a_number_flag_takes_no_nan_or_infinity(tmp_path: Path, flag: str, value: str,
                                                capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as stop:
        _render(tmp_path / "s", f"{flag}={value}")
    assert stop.value.code == 2
    assert f"argument {flag}: must be a finite number" in capsys.readouterr().err
    assert not (tmp_path / "s").exists()


def test_synth_refuses_an_image_it_could_not_render(tmp_path: Path,
                                                    capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["synth", str(tmp_path / "s"), "--width", "100000", "--quiet"]) == 2
    assert "width=100000 is out of range" in capsys.readouterr().err
    assert main(["synth", str(tmp_path / "t"), "--session", "--targets", "100000",
                 "--width", "160", "--height", "120", "--quiet"]) == 2
    assert "--targets must be 0 to 1000" in capsys.readouterr().err
    assert not (tmp_path / "s").exists() and not (tmp_path / "t").exists()


@pytest.fixture(scope="module")
def two_scenes(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    """Two scenes rendered in place by ``rigkit synth`` (their files in its ledger, as a
    user's are: a copy would not be)."""
    root = tmp_path_factory.mktemp("rendered")
    scenes = root / "s7", root / "s9"
    for seed, scene in zip((7, 9), scenes, strict=True):
        assert main(["synth", str(scene), "--seed", str(seed), "--width", "256",
                     "--height", "192", "--quiet"]) == 0
    return scenes


@pytest.mark.parametrize("case", ["depth onto the truth", "preview onto a frame",
                                  "raw log onto a frame", "log onto the truth"])
def test_a_scene_rigkit_rendered_is_an_input_no_other_command_writes_over(
    two_scenes: tuple[Path, Path], capsys: pytest.CaptureFixture[str], case: str,
) -> None:
    """Before: each of these was written over the scene's file, exit 0: the scene's files
    were in rigkit's ledger, and any command took them for its own. ``rigkit eval`` then
    scored a depth map against itself (100 %)."""
    s7, s9 = two_scenes
    kept = _digests(*[p for s in two_scenes for p in s.rglob("*")
                      if p.is_file() and p.name != LEDGER])
    depth = ["depth", str(s7 / "left.png"), str(s7 / "right.png"), str(s7 / "back.png"),
             "--focal-px", "2442.4", "--baseline-lr", "2", "--baseline-lb", "2", "--quiet"]
    truth = s7 / "ground_truth" / "depth_left.npy"
    argv = {
        "depth onto the truth": [*depth, "--out", str(truth)],
        "preview onto a frame": [*depth, "--out", str(s9 / "left.npy"), "--preview"],
        "raw log onto a frame": ["rangefinder", "read", "--port", "sim://trupulse",
                                 "--timeout", "2", "--raw-log", str(s9 / "right.png")],
        "log onto the truth": ["rangefinder", "log", "--port", "sim://trupulse",
                               "--count", "1", "--output", str(truth)],
    }[case]
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1, err
    assert "part of a scene that rigkit synth rendered" in err, err
    assert _digests(*kept) == kept
