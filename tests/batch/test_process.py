"""Batch processing of sessions: results, the comparisons log, failures, idempotence."""

from __future__ import annotations

import json
import math
import os
from pathlib import Path

import numpy as np
import pytest

from rigkit.batch import (
    auto_jobs,
    compare_target,
    process_session,
    run_batch,
)
from rigkit.batch.compare import SCATTER_GAIN, median_scatter
from rigkit.capture import Target, load_session
from rigkit.capture.comparisons import LOG_NAME, SIGNIFICANT_DIGITS, latest_run, read_rows
from rigkit.cli import main
from rigkit.core.files import recover_folder
from rigkit.errors import InputError
from rigkit.pipeline.lens import Lens
from tests.conftest import copy_session


def true_ranges(session_dir: Path) -> dict[str, float]:
    """Each target's true range, recorded in its note by the synthetic session writer."""
    return {
        t.name: float(t.note.split()[2]) for t in load_session(session_dir).targets
    }


def _kept(*values: float) -> float:
    """How far the CSV's values may be from those computed: half a unit in the last of
    the significant digits it keeps, for each of ``values``."""
    return sum(0.5 * abs(v) * 10.0 ** (1 - SIGNIFICANT_DIGITS) for v in values)


def test_log_rows_agree_with_ground_truth(processed_session: Path) -> None:
    rows = read_rows(processed_session / LOG_NAME)
    truth = true_ranges(processed_session)
    assert [r.target for r in rows] == ["T1", "T2", "T3", "T4", "T5"]
    for row in rows:
        assert row.status == "ok" and row.valid_fraction > 0.9
        assert row.laser_range_m == pytest.approx(truth[row.target], abs=0.25)
        # 960 px images: the offset is known to ~1 %; full resolution does 5x better.
        assert row.estimate_range_m == pytest.approx(truth[row.target], rel=0.015)
        # The error against an independent value, the true range...
        assert abs(row.error_m - (truth[row.target] - row.laser_range_m)) < 0.015 * truth[
            row.target] + 0.25
        # ...and its columns consistent at the precision the CSV keeps of each.
        assert abs(row.error_m - (row.estimate_range_m - row.laser_range_m)) <= _kept(
            row.error_m, row.estimate_range_m, row.laser_range_m)
        assert abs(row.error_pct - 100 * row.error_m / row.laser_range_m) <= _kept(
            row.error_pct) + 100 * _kept(row.error_m) / row.laser_range_m
        assert 0 < row.estimate_sigma_m < 0.02 * row.estimate_range_m


def test_results_folder_is_complete(processed_session: Path) -> None:
    results = processed_session / "results"
    names = {p.name for p in results.iterdir()}
    assert names == {"depth.npy", "sigma.npy", "depth.json", "depth.png", "sigma.png",
                     "left.png", "grey.png", "flags.npy", "comparisons.csv"}
    depth = np.load(results / "depth.npy")
    assert depth.shape == (720, 960) and depth.dtype == np.float32
    meta = json.loads((results / "depth.json").read_text())
    assert meta["run_id"] == "20260101T000000Z-0001"
    assert meta["frames"]["left"][0]["sha256"] == load_session(processed_session).frames[
        "left"].sha256
    assert "run 20260101T000000Z-0001: ok" in (processed_session / "history.log").read_text()
    assert not list(processed_session.glob(".results*"))


def test_reprocessing_replaces_results_and_keeps_history(
    processed_small: Path, tmp_path: Path
) -> None:
    copy = copy_session(processed_small, tmp_path)
    raw_before = {p.name: p.read_bytes() for p in (copy / "raw").iterdir()}
    process_session(copy, "20260102T000000Z-0002")
    meta = json.loads((copy / "results" / "depth.json").read_text())
    assert meta["run_id"] == "20260102T000000Z-0002"
    rows = read_rows(copy / LOG_NAME)
    assert len(rows) == 10
    assert {r.run_id for r in latest_run(rows)} == {"20260102T000000Z-0002"}
    assert {p.name: p.read_bytes() for p in (copy / "raw").iterdir()} == raw_before


def test_a_failed_write_leaves_the_old_results(
    processed_small: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    copy = copy_session(processed_small, tmp_path)
    before = (copy / "results" / "depth.json").read_text()

    def broken(img: np.ndarray, compression: int | None = None) -> bytes:
        raise OSError("disk full")

    monkeypatch.setattr("rigkit.core.files.encode_png", broken)
    with pytest.raises(OSError):
        process_session(copy, "20260103T000000Z-0003")
    assert (copy / "results" / "depth.json").read_text() == before
    assert not list(copy.glob(".results*"))
    assert len(read_rows(copy / LOG_NAME)) == 5


def test_an_interrupted_swap_is_undone(processed_small: Path, tmp_path: Path) -> None:
    copy = copy_session(processed_small, tmp_path)
    os.rename(copy / "results", copy / ".results-old-20260104T000000Z-0004")
    (copy / ".results-20260105T000000Z-0005").mkdir()
    recover_folder(copy, "results")
    assert (copy / "results" / "depth.npy").is_file()
    assert not list(copy.glob(".results*"))


def test_batch_goes_on_after_a_failure(
    small_session: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    good = copy_session(small_session, tmp_path, "good")
    missing = copy_session(small_session, tmp_path, "missing-frame",
                           edit=lambda data: data["frames"].pop("back"))
    absent = tmp_path / "no-such-session"
    code = main(["process", str(missing), str(absent), str(good), "--jobs", "1", "--quiet"])
    assert code == 1
    out = capsys.readouterr().out
    assert "1 processed, 2 failed" in out
    assert f"FAILED {missing}: no back frame" in out
    assert f"FAILED {absent}: no such session folder" in out
    assert (good / "results" / "depth.npy").is_file()
    assert not (missing / "results").exists()
    assert "FAILED: " in (missing / "history.log").read_text()


@pytest.mark.parametrize(
    ("edit", "message"),
    [
        (lambda d: d["targets"][0].update(pixel=[5000.0, 10.0]),
         "target 'T1' pixel \\(5000, 10\\) is outside the 960x720 left image"),
        (lambda d: d["frames"]["right"].update(file="raw/gone.png"),
         "right frame raw/gone.png is missing"),
    ],
)
def test_bad_sessions_fail_with_one_line(
    synth_session: Path, tmp_path: Path, edit, message: str
) -> None:
    copy = copy_session(synth_session, tmp_path, edit=edit)
    with pytest.raises(InputError, match=message):
        process_session(copy, "20260106T000000Z-0006")


@pytest.mark.slow
def test_parallel_batch(small_session: Path, tmp_path: Path) -> None:
    paths = [copy_session(small_session, tmp_path, f"s{i}") for i in range(2)]
    seen: list[tuple[str, str]] = []
    outcomes = run_batch(paths, 2, progress=lambda p, stage, f: seen.append((p.name, stage)))
    assert [o.ok for o in outcomes] == [True, True]
    assert [o.path for o in outcomes] == paths
    assert {("s0", "stereo"), ("s1", "stereo"), ("s0", "done")} <= set(seen)
    run_ids = {r.run_id for p in paths for r in read_rows(p / LOG_NAME)}
    assert len(run_ids) == 1


def test_one_session_named_twice_is_processed_once(small_session: Path, tmp_path: Path,
                                                    capsys: pytest.CaptureFixture[str]) -> None:
    """Before: a session given directly and by a link ran twice at once, and the second
    found it locked by the first and said it failed (in its history too)."""
    session = copy_session(small_session, tmp_path, "s")
    (tmp_path / "link").symlink_to(session)
    assert main(["process", str(session), str(tmp_path / "link"), f"{session}/",
                 "--jobs", "2", "--quiet"]) == 0
    out = capsys.readouterr()
    assert "1 processed, 0 failed" in out.out and "1 session(s)" in out.err
    assert "FAILED" not in (session / "history.log").read_text()


def test_jobs_follow_memory_and_cores(synth_session: Path) -> None:
    paths = [synth_session] * 8
    assert auto_jobs(paths, available_bytes=10**8) == 1
    assert auto_jobs(paths, available_bytes=10**13) == min(8, os.cpu_count() or 1)
    assert auto_jobs(paths[:1], available_bytes=10**13) == 1


def test_range_from_depth_on_a_plane(synth_session: Path) -> None:
    """z = 300 m everywhere: the range at a pixel is z * |(x, y, 1)| from the camera."""
    session = load_session(synth_session)
    f = session.rig().focal_px
    depth = np.full((720, 960), 300.0, np.float32)
    sigma = np.full((720, 960), 1.5, np.float32)
    target = Target("A", (900.0, 40.0), 9, session.targets[0].readings)
    lens = Lens(f, (960, 720))
    row = compare_target(session, target, depth, sigma, "run", lens)
    x, y = (900.0 - 479.5) / f, (40.0 - 359.5) / f
    expected = 300.0 * math.sqrt(1 + x * x + y * y)
    assert row.estimate_range_m == pytest.approx(expected, rel=1e-9)
    # A plane scatters nothing: the median's sigma is the per-pixel one over the root of
    # the window's pixels (the least it could be), with the offset's share added.
    own = 1.2533 * 1.5 / 9
    assert row.estimate_sigma_m == pytest.approx(own * expected / 300.0)
    offset_row = compare_target(session, target, depth, sigma, "run", lens, (0.004, 300.0))
    assert offset_row.estimate_sigma_m == pytest.approx(
        math.hypot(own, 1.2) * expected / 300.0)
    # Through a bent lens: the recorded pixel's ray is the undistorted one.
    bent = Lens(f, (960, 720), (40.0, 0.0, 0.0, 0.0, 0.0))
    row = compare_target(session, target, depth, sigma, "run", bent)
    x, y = (bent.to_ideal(np.array([[900.0, 40.0]]))[0] - [479.5, 359.5]) / f
    assert row.estimate_range_m == pytest.approx(300.0 * math.sqrt(1 + x * x + y * y),
                                                 rel=1e-12)
    assert row.estimate_range_m < expected - 1e-3  # the lens pushed the corner outwards
    depth[:, :] = np.nan
    row = compare_target(session, target, depth, sigma, "run", Lens(f, (960, 720)))
    assert row.status == "no_estimate" and math.isnan(row.error_pct)


def _blocky(sigma: float, side: int, seed: int, shape=(720, 960)) -> np.ndarray:
    """300 m plus a tilt, plus an error constant over each ``side``-px block, one sigma
    ``sigma`` (relative): each window-sized median is off by one draw of it."""
    rng = np.random.default_rng(seed)
    rows, cols = np.indices(shape)
    blocks = rng.normal(0.0, sigma, (shape[0] // side + 1, shape[1] // side + 1))
    return (300.0 + 0.01 * cols + 0.02 * rows) * (1 + blocks[rows // side, cols // side])


def test_a_targets_sigma_is_what_its_windows_median_scatters() -> None:
    """Errors shared by each window-sized patch, 0.2 % apart, on a sloping plane: the
    measured sigma of a target's median is that 0.2 % (times the gain that covers what
    scatters beyond its neighbourhood), whatever the per-pixel sigma says; 0 for none."""
    found = [median_scatter(_blocky(0.002, 9, seed), 480 + 4, 360 + 4, 9)
             for seed in range(12)]
    assert np.median(found) == pytest.approx(SCATTER_GAIN * 0.002, rel=0.2)
    assert median_scatter(_blocky(0.0, 9, 0), 484, 364, 9) == pytest.approx(0.0, abs=1e-9)
    sky = np.full((720, 960), np.nan)
    assert math.isnan(median_scatter(sky, 480, 360, 9))  # nothing measures it


def test_a_session_being_processed_is_refused(small_session: Path, tmp_path: Path) -> None:
    import fcntl

    copy = copy_session(small_session, tmp_path)
    with open(copy / ".lock", "a") as handle:
        fcntl.flock(handle, fcntl.LOCK_EX)
        with pytest.raises(InputError, match="busy: another rigkit command holds it"):
            process_session(copy, "20260107T000000Z-0007")
    assert not (copy / "results").exists()


@pytest.mark.slow
def test_a_session_with_bursts_and_a_lens_profile(tmp_path: Path) -> None:
    """Three frames per position with shimmer, and a distorting lens the rig profile
    names: processed end to end, the burst stacked, the lens recorded."""
    from dataclasses import replace

    import yaml

    from rigkit.synth import SynthParams, generate_scene
    from rigkit.synth.session import RIG_FILE, write_synthetic_session

    k1 = 0.002 / ((640**2 + 480**2) / 4 / SynthParams(width=640).focal_px**2)
    params = replace(SynthParams(width=640, height=480, max_pp_offset_px=0.0), burst=3,
                     shimmer_px=0.1, shimmer_corr_px=8.0, distortion=(k1, 0, 0, 0, 0))
    out = tmp_path / "burst"
    write_synthetic_session(generate_scene(params, seed=5), out, n_targets=3, seed=5)
    session = load_session(out)
    assert all(len(session.bursts[p]) == 3 for p in ("left", "right", "back"))
    # The rig profile carries the lens: the session's copy of it is what processing uses.
    assert session.rig().distortion == (k1, 0, 0, 0, 0)
    outcome = process_session(out, "20260101T000000Z-0002")
    assert outcome.ok, outcome.message
    meta = json.loads((out / "results" / "depth.json").read_text())
    assert [len(meta["frames"][p]) for p in ("left", "right", "back")] == [3, 3, 3]
    assert meta["rig"]["distortion"][0] == pytest.approx(k1)
    # The shimmer measured between the left burst's first two frames (0.1 px rendered,
    # over 8 px: at 640 px the tracker's 21 px window averages some of it away).
    assert meta["shimmer"]["frames"] == "left frames 1 and 2"
    assert 0.04 < meta["shimmer"]["rms_px"] < 0.15
    rows = read_rows(out / LOG_NAME)
    # 640 px frames: the offset, and so the range, is good to a few % (its sigma says so).
    assert rows and all(abs(r.error_m) < 3 * r.estimate_sigma_m + 0.2 for r in rows)
    assert all(abs(r.error_pct) < 5 for r in rows)
    assert yaml.safe_load((out / RIG_FILE).read_text())["camera"]["distortion"]["k1"] == k1


def test_session_show_says_processed_after_a_run(processed_session: Path, capsys) -> None:
    assert main(["session", "show", str(processed_session)]) == 0
    shown = capsys.readouterr().out
    assert "status   processed (run 20260101T000000Z-0001)" in shown
    assert "ready to process" not in shown
