"""Capture sessions: session.yaml round trip, frame ingest, targets, validation errors."""

from __future__ import annotations

import hashlib
from pathlib import Path

import cv2
import numpy as np
import pytest

from rigkit.capture import (
    LaserReading,
    add_frame,
    add_target,
    create_session,
    frame_problems,
    load_session,
)
from rigkit.cli import main
from rigkit.errors import InputError
from rigkit.synth import load_scene
from tests.conftest import copy_session, rig_file

RIG = Path(__file__).resolve().parents[2] / "rigs" / "synthetic.yaml"


def sha(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def png(path: Path, size: tuple[int, int] = (64, 48), seed: int = 0) -> Path:
    """A textured frame (smoothed noise: a picture, not noise) of ``size`` px."""
    rng = np.random.default_rng(seed)
    noise = cv2.GaussianBlur(rng.random((size[1], size[0])), (0, 0), 2.0)
    cv2.imwrite(str(path), cv2.normalize(noise, None, 0, 255, cv2.NORM_MINMAX).astype(np.uint8))
    return path


def small_rig(folder: Path) -> Path:
    """The synthetic rig for the 64x48 px frames of :func:`png`."""
    return rig_file(folder, (64, 48))


def new_session(folder: Path):
    """A new session ``folder/s`` with the rig of :func:`small_rig`."""
    return create_session(folder / "s", small_rig(folder))


def test_new_session_keeps_a_copy_of_the_rig(tmp_path: Path) -> None:
    session = create_session(tmp_path / "s1", RIG, operator="A. Field", notes="windy")
    again = load_session(tmp_path / "s1")
    assert again == session
    assert again.rig().focal_px == pytest.approx(43962.93892852579)
    assert again.rig_sha256 == sha(RIG)
    assert (tmp_path / "s1" / "raw").is_dir()
    assert "new" in (tmp_path / "s1" / "history.log").read_text()
    with pytest.raises(InputError, match="already a session"):
        create_session(tmp_path / "s1", RIG)


def test_bad_rig_writes_nothing(tmp_path: Path) -> None:
    bad = tmp_path / "bad.yaml"
    bad.write_text("version: 1\nname: x\n")
    with pytest.raises(InputError, match="bad.yaml"):
        create_session(tmp_path / "s1", bad)
    assert not (tmp_path / "s1").exists()


def test_add_frame_copies_byte_for_byte(tmp_path: Path) -> None:
    source = png(tmp_path / "DSC_0001.png")
    before = sha(source)
    session = add_frame(new_session(tmp_path), "left", source)
    frame = session.frames["left"]
    stored = tmp_path / "s" / frame.file
    assert frame.file == "raw/DSC_0001.png"
    assert sha(stored) == frame.sha256 == before == sha(source)
    assert frame.size_px == (64, 48)
    assert load_session(tmp_path / "s").frames["left"] == frame


def test_replacing_a_frame_keeps_the_old_file(tmp_path: Path) -> None:
    session = add_frame(new_session(tmp_path), "left", png(tmp_path / "a.png"))
    with pytest.raises(InputError, match="already has a left frame"):
        add_frame(session, "left", png(tmp_path / "b.png", seed=1))
    session = add_frame(session, "left", png(tmp_path / "b.png", seed=1), replace_existing=True)
    assert session.frames["left"].file == "raw/b.png"
    assert (tmp_path / "s" / "raw" / "a.png").is_file()


def test_same_name_different_content_is_not_overwritten(tmp_path: Path) -> None:
    (tmp_path / "day1").mkdir()
    (tmp_path / "day2").mkdir()
    first = png(tmp_path / "day1" / "IMG.png", seed=1)
    second = png(tmp_path / "day2" / "IMG.png", seed=2)
    session = add_frame(new_session(tmp_path), "left", first)
    session = add_frame(session, "right", second)
    assert session.frames["right"].file == "raw/right-IMG.png"
    assert sha(tmp_path / "s" / "raw" / "IMG.png") == sha(first)


def test_unreadable_frame_never_enters_raw(tmp_path: Path) -> None:
    garbage = tmp_path / "DSC_0002.NEF"
    garbage.write_bytes(b"not a raw file" * 100)
    session = new_session(tmp_path)
    with pytest.raises(InputError, match="DSC_0002.NEF"):
        add_frame(session, "left", garbage)
    assert list((tmp_path / "s" / "raw").iterdir()) == []
    assert load_session(tmp_path / "s").frames == {}


def test_frames_must_share_a_size(tmp_path: Path) -> None:
    session = add_frame(new_session(tmp_path), "left", png(tmp_path / "a.png"))
    with pytest.raises(InputError, match="64x48"):
        add_frame(session, "right", png(tmp_path / "b.png", size=(80, 48)))


def test_targets_outside_the_image_and_even_windows_are_refused(tmp_path: Path) -> None:
    session = add_frame(new_session(tmp_path), "left", png(tmp_path / "a.png"))
    reading = [LaserReading(300.0, "2026-11-22T10:00:00Z", "manual")]
    with pytest.raises(InputError, match=r"outside the 64x48 left image"):
        add_target(session, "T1", (64.0, 10.0), readings=reading)
    with pytest.raises(InputError, match="odd"):
        add_target(session, "T1", (10.0, 10.0), window_px=8, readings=reading)
    with pytest.raises(InputError, match="can measure"):
        add_target(session, "T1", (10.0, 10.0), readings=[LaserReading(-1, "t", "manual")])


def test_more_readings_for_a_target(tmp_path: Path) -> None:
    session = add_frame(new_session(tmp_path), "left", png(tmp_path / "a.png"))
    session = add_target(session, "mast", (10, 20), readings=[LaserReading(301.0, "t", "manual")])
    session = add_target(session, "mast", (10, 20), readings=[LaserReading(301.4, "t", "manual")])
    assert [r.slope_distance_m for r in load_session(session.path).target("mast").readings] == [
        301.0, 301.4
    ]
    with pytest.raises(InputError, match="already at pixel"):
        add_target(session, "mast", (11, 20))


def test_problems_name_missing_and_altered_frames(synth_session: Path, tmp_path: Path) -> None:
    copy = copy_session(synth_session, tmp_path)
    assert frame_problems(load_session(copy)) == []
    (copy / "raw" / "back.png").unlink()
    with (copy / "raw" / "right.png").open("ab") as handle:
        handle.write(b"\0")
    problems = frame_problems(load_session(copy))
    assert any("back frame raw/back.png is missing" in p for p in problems)
    assert any("right frame raw/right.png no longer matches" in p for p in problems)


@pytest.mark.parametrize(
    ("edit", "message"),
    [
        (lambda d: d.update(extra=1), "extra: unknown key"),
        (lambda d: d["targets"][0].update(window_px=4), r"targets\[0\].window_px"),
        (lambda d: d["targets"][0].update(pixel=[1]), r"targets\[0\].pixel"),
        (lambda d: d["frames"]["left"].update(file="/etc/passwd"), "frames.left.file"),
        (lambda d: d["rig"]["values"]["baselines"]["C_lr"].update(value_m=-2),
         "rig.values.baselines.C_lr"),
        (lambda d: d["targets"][0]["readings"][0].update(slope_distance_m="far"),
         r"readings\[0\].slope_distance_m"),
        (lambda d: d.update(format="other/9"), "format"),
    ],
)
def test_bad_session_yaml_names_file_and_key(
    synth_session: Path, tmp_path: Path, edit, message: str
) -> None:
    copy = copy_session(synth_session, tmp_path, edit=edit)
    with pytest.raises(InputError, match=message) as info:
        load_session(copy)
    assert "session.yaml" in str(info.value)


def test_cli_session_workflow(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    s = str(tmp_path / "field-1")
    assert main(["session", "new", s, "--rig", str(small_rig(tmp_path)), "--notes", "test"]) == 0
    for i, position in enumerate(("left", "right", "back")):
        frame = png(tmp_path / f"{position}.png", seed=i)
        assert main(["session", "add-frame", s, "--position", position, str(frame)]) == 0
    assert main(["session", "add-target", s, "--pixel", "30", "20", "--range-m", "300.5",
                 "300.7"]) == 0
    assert main(["session", "add-target", s, "--pixel", "99", "20", "--range-m", "300"]) == 2
    assert "outside the 64x48 left image" in capsys.readouterr().err
    assert main(["session", "show", s]) == 0
    shown = capsys.readouterr().out
    assert "T1" in shown and "1: 300.50, 2: 300.70" in shown and "ready to process" in shown
    assert main(["session", "show", s, "--json"]) == 0


def test_cli_target_from_a_simulated_rangefinder(tmp_path: Path) -> None:
    s = tmp_path / "field-2"
    create_session(s, small_rig(tmp_path))
    add_frame(load_session(s), "left", png(tmp_path / "left.png"))
    code = main(["session", "add-target", str(s), "--name", "barn", "--pixel", "20", "20",
                 "--device", "sim://trupulse?distance=412.3&interval=0.01", "--shots", "2",
                 "--timeout", "5"])
    assert code == 0
    readings = load_session(s).target("barn").readings
    assert len(readings) == 2
    assert readings[0].source.startswith("trupulse:sim://")
    assert readings[0].slope_distance_m == pytest.approx(412.3, abs=1.0)
    assert readings[0].raw and readings[0].raw.startswith("$PLTIT")


def test_synth_writes_a_session_with_true_laser_targets(tmp_path: Path) -> None:
    out = tmp_path / "synth-9"
    assert main(["synth", str(out), "--seed", "9", "--width", "320", "--height", "240",
                 "--session", "--targets", "3", "--laser-noise", "0", "--quiet"]) == 0
    session = load_session(out)
    assert [t.name for t in session.targets] == ["T1", "T2", "T3"]
    assert sorted(p.name for p in (out / "raw").iterdir()) == ["back.png", "left.png",
                                                               "right.png"]
    assert not (out / "left.png").exists()
    # The record of where a frame came from does not depend on the machine.
    assert {f.source for f in session.frames.values()} == {"rendered by rigkit synth, seed 9"}
    truth = load_scene(out)
    K = truth.cameras["left"].K
    for target in session.targets:
        (reading,) = target.readings
        u, v = (int(c) for c in target.pixel)
        ray = np.linalg.solve(K, [u, v, 1.0])  # z = 1 on the pixel's ray
        expected = truth.depth("left")[v, u] * np.linalg.norm(ray)
        assert reading.slope_distance_m == pytest.approx(expected, abs=1e-3)
        assert reading.slope_distance_m == pytest.approx(float(target.note.split()[2]))
        assert reading.source == "simulated"
    assert session.rig().focal_px == pytest.approx(160 / np.tan(np.radians(3)))


def test_bundled_example_records_no_machine_path() -> None:
    example = load_session(RIG.parents[1] / "capture" / "example")
    assert {f.source for f in example.frames.values()} == {"rendered by rigkit synth, seed 7"}
    assert frame_problems(example) == []


def test_a_burst_is_listed_in_order_and_read_back(tmp_path: Path) -> None:
    session = add_frame(new_session(tmp_path), "left", png(tmp_path / "a.png"))
    session = add_frame(session, "left", png(tmp_path / "b.png", seed=1), burst=True)
    session = add_frame(session, "left", png(tmp_path / "c.png", seed=2), burst=True)
    files = [f.file for f in session.bursts["left"]]
    assert files == ["raw/a.png", "raw/b.png", "raw/c.png"]
    assert session.burst_length == 3  # the shortest burst among positions with frames
    assert session.frames["left"].file == "raw/a.png"  # the first fixes the grid
    again = load_session(tmp_path / "s")
    assert again.bursts["left"] == session.bursts["left"]
    text = (tmp_path / "s" / "session.yaml").read_text()
    assert text.count("file: raw/") == 3 and text.count("sha256:") == 4  # and the rig's
    # a retake replaces the whole burst, and every file stays
    session = add_frame(session, "left", png(tmp_path / "d.png", seed=3), replace_existing=True)
    assert [f.file for f in session.bursts["left"]] == ["raw/d.png"]
    assert all((tmp_path / "s" / "raw" / n).is_file() for n in ("a.png", "b.png", "c.png"))


def test_a_burst_refuses_the_same_exposure_twice_and_another_size(tmp_path: Path) -> None:
    session = add_frame(new_session(tmp_path), "left", png(tmp_path / "a.png"))
    with pytest.raises(InputError, match="a.png is the same file as raw/a.png, given twice in "
                       "the burst"):
        add_frame(session, "left", tmp_path / "a.png", burst=True)
    with pytest.raises(InputError, match="80x60 px, but the rig profile synthetic is for 64x48"):
        add_frame(session, "left", png(tmp_path / "big.png", size=(80, 60)), burst=True)
