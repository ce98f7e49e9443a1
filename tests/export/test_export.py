"""``rigkit export``: PLY, LAS, LAZ and TIFF from a session or a depth map file, point
for point; chunks, --step, atomic output and one-line errors."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import cv2
import numpy as np
import pytest

from rigkit.cli import main
from rigkit.errors import InputError
from rigkit.export import export_path
from rigkit.export.source import open_depth
from rigkit.rangefinder.ranging import range_on_ray
from tests.conftest import make_record
from tests.export.helpers import SIZE, depth_plane, new_session, read_ply


def test_points_are_the_pixels_back_projected_as_the_laser_comparison_does(
    tmp_path: Path,
) -> None:
    session = new_session(tmp_path)
    export_path(session, tmp_path / "out", ["ply"], step=3)
    ply = read_ply(tmp_path / "out" / "geo.ply")
    depth = depth_plane()
    grid = depth[::3, ::3]
    assert len(ply) == np.isfinite(grid).sum()
    # The last grid point: pixel (399, 297), its range from the camera as the comparison has it.
    u, v = (SIZE[0] - 1) // 3 * 3, (SIZE[1] - 1) // 3 * 3
    last = ply[-1]
    ray = open_depth(session).lens.rays(np.array([[u, v]], np.float64))[0]
    expected = range_on_ray(float(depth[v, u]), (ray[0], ray[1], ray[2]))
    assert float(np.linalg.norm([last["x"], last["y"], last["z"]])) == pytest.approx(
        expected, rel=1e-6)
    assert last["x"] > 0 and last["y"] > 0  # right of and below the centre: x right, y down
    assert last["sigma"] == pytest.approx(0.01 * depth[v, u])


def test_chunks_give_the_same_file_as_one_pass(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    session = new_session(tmp_path)
    export_path(session, tmp_path / "one", ["ply", "las"])
    monkeypatch.setattr("rigkit.export.points.CHUNK_POINTS", 1000)  # 2 rows at a time
    export_path(session, tmp_path / "many", ["ply", "las"])
    for name in ("geo.ply", "geo.las"):
        assert (tmp_path / "one" / name).read_bytes() == (tmp_path / "many" / name).read_bytes()


def test_a_depth_map_file_from_rigkit_depth(tmp_path: Path) -> None:
    """D.npy with D.sigma.npy, D.grey.png and D.json: the intrinsics from D.json."""
    depth = depth_plane()
    np.save(tmp_path / "d.npy", depth)
    np.save(tmp_path / "d.sigma.npy", depth * np.float32(0.01))
    cv2.imwrite(str(tmp_path / "d.grey.png"), np.full(depth.shape, 77, np.uint8))
    record = make_record(rig_name="bench", left_camera_px=(4000.0, 100.0, 50.0))
    (tmp_path / "d.json").write_text(record.to_json())
    done = export_path(tmp_path / "d.npy", tmp_path / "out", ["ply"])
    ply = read_ply(tmp_path / "out" / "d.ply")
    first = ply[0]  # pixel (20, 0): the top-left corner is NaN
    assert first["x"] == pytest.approx((20 - 100.0) / 4000.0 * depth[0, 20], rel=1e-6)
    assert first["y"] == pytest.approx((0 - 50.0) / 4000.0 * depth[0, 20], rel=1e-6)
    assert set(ply["red"]) == {77} and done.georef is None
    # A D.json without the intrinsics (an older rigkit's): refused, not guessed.
    meta = json.loads(record.to_json())
    del meta["left_camera_px"]
    (tmp_path / "d.json").write_text(json.dumps(meta))
    with pytest.raises(InputError, match=r"d\.json: left_camera_px: missing"):
        export_path(tmp_path / "d.npy", tmp_path / "old", ["ply"])
    assert not (tmp_path / "old").exists()


def test_infinite_depths_are_no_points_and_a_reach_las_cannot_hold_is_one_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A map that no run of rigkit's wrote: +-inf are left out as NaN is; depths beyond
    what LAS's 32-bit coordinates hold at 1 m are refused for LAS, not a traceback."""
    depth = depth_plane()
    depth[100:110, :] = np.inf
    depth[120, :] = -np.inf
    session = new_session(tmp_path, depth=depth)
    done = export_path(session, tmp_path / "out", ["ply", "las"])
    assert done.points == int(np.isfinite(depth).sum())
    depth[50, 50] = 1e13
    far = new_session(tmp_path, "far", depth=depth)
    assert main(["export", str(far), "--out", str(tmp_path / "far-out"), "--format",
                 "las", "--quiet"]) == 2
    err = capsys.readouterr().err.strip()
    assert "do not fit a LAS file" in err and len(err.splitlines()) == 1


def test_results_of_other_frames_are_not_exported(tmp_path: Path,
                                                  capsys: pytest.CaptureFixture[str]) -> None:
    """A depth map from frames the session no longer holds is no map of it."""
    session = new_session(tmp_path)
    meta = json.loads((session / "results" / "depth.json").read_text())
    meta["frames"]["left"] = [{"file": "raw/left.png", "sha256": "0" * 64}]
    (session / "results" / "depth.json").write_text(json.dumps(meta))
    assert main(["export", str(session), "--out", str(tmp_path / "out"), "--quiet"]) == 2
    err = capsys.readouterr().err.strip()
    assert "before the frames changed" in err and len(err.splitlines()) == 1


def test_a_failure_leaves_no_partial_output(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    session = new_session(tmp_path)
    out = tmp_path / "out"
    export_path(session, out, ["ply"])  # the previous export
    before = (out / "geo.ply").read_bytes()
    monkeypatch.setattr("rigkit.export.points.CHUNK_POINTS", 1000)
    calls = []

    def full_disk(self, chunk) -> None:
        calls.append(1)
        if len(calls) > 3:
            raise OSError(28, "No space left on device")

    monkeypatch.setattr("rigkit.export.las.LasWriter.write", full_disk)
    with pytest.raises(InputError, match="cannot write the export .No space left on device."):
        export_path(session, out, ["ply", "las"])
    assert sorted(p.name for p in out.iterdir()) == [  # no .las, no temporary folder
        ".rigkit-outputs", "geo.export.json", "geo.ply"]
    assert (out / "geo.ply").read_bytes() == before


@pytest.mark.parametrize(("setup", "message"), [
    (lambda p: (p / "results" / "grey.png").unlink(),
     "grey.png: missing (written since rigkit records the grey values for export); run "
     "`rigkit process"),
    (lambda p: shutil.rmtree(p / "results"), "no results yet; run `rigkit process"),
    (lambda p: np.save(p / "results" / "sigma.npy", np.zeros((3, 3), np.float32)),
     "must be one (H, W) size"),
    (lambda p: (p / "session.yaml").unlink(), "not a session folder"),
])
def test_bad_inputs_get_one_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], setup, message: str
) -> None:
    session = new_session(tmp_path)
    setup(session)
    assert main(["export", str(session), "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err.strip()
    assert message in err and len(err.splitlines()) == 1


def test_bad_options_get_one_line(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    session = new_session(tmp_path)
    out = ["--out", str(tmp_path / "out")]
    assert main(["export", str(session), *out, "--format", "ply,obj"]) == 2
    assert "--format 'ply,obj': choose from ply, las, laz, tif" in capsys.readouterr().err
    with pytest.raises(SystemExit):  # argparse: usage and the reason, exit status 2
        main(["export", str(session), *out, "--step", "0"])
    assert "must be at least 1, got 0" in capsys.readouterr().err
