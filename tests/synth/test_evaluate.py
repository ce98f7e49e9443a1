"""Evaluation on estimates with known, injected errors."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from rigkit.errors import InputError
from rigkit.synth import SynthParams, generate_scene, load_scene, write_scene
from rigkit.synth.evaluate import (
    TEXTURE_MARGIN_PX,
    ChangeMetrics,
    change_metrics,
    depth_metrics,
    evaluate_scenes,
    format_table,
    visible_in_right,
    write_csv,
)


@pytest.fixture(scope="module")
def judged(truth):
    return visible_in_right(truth)


def test_ground_truth_scores_perfectly(truth, judged) -> None:
    gt = truth.depth("left")
    m = depth_metrics(gt, gt, judged)
    assert m.under_0_5 == m.under_1 == m.under_3 == m.density == 1.0 and m.median_bias == 0


def test_scaled_depth_falls_between_thresholds(truth, judged) -> None:
    gt = truth.depth("left")
    m = depth_metrics(gt * 1.015, gt, judged)
    assert m.under_1 == 0.0 and m.under_2 == 1.0
    assert m.median_bias == pytest.approx(0.015, abs=1e-6)


def test_missing_pixels_count_as_misses(truth, judged) -> None:
    gt = truth.depth("left")
    est = gt.copy()
    est[: gt.shape[0] // 2] = np.nan
    m = depth_metrics(est, gt, judged)
    expected = judged[gt.shape[0] // 2 :].sum() / judged.sum()
    assert m.density == pytest.approx(expected) and m.under_1 == pytest.approx(expected)


def test_visibility_excludes_what_the_right_camera_cannot_see(truth, judged) -> None:
    # The right camera is rotated and 2 m to the side: part of the left view is unseen,
    # but most of it is seen.
    assert 0.3 < judged.mean() < 0.999


def test_missing_estimate_is_a_failure_that_says_where_it_looked(scene_dir, tmp_path) -> None:
    rows = evaluate_scenes([scene_dir], tmp_path)
    assert rows[0].failed and "no depth estimate (looked for " in rows[0].reason
    assert f"{tmp_path / scene_dir.name}-depth.npy" in rows[0].reason
    assert "failures: 1 of 1" in format_table(rows)


@pytest.mark.parametrize("write, said", [
    (lambda path, shape: path.write_text("junk\n"), "not a NumPy array file (.npy)"),
    (lambda path, shape: np.save(path, np.ones(shape, np.complex128)),
     "not an (H, W) map of real depths (complex128"),
    (lambda path, shape: np.save(path, -np.ones(shape, np.float32)), "no positive finite depth"),
    (lambda path, shape: np.save(path, np.full(shape, np.inf, np.float32)),
     "no positive finite depth"),
])
def test_an_estimate_that_is_no_depth_map_is_a_failure(scene_dir, truth, tmp_path, write,
                                                       said) -> None:
    """Before: a complex, an all-negative or an all-inf map was scored 0.00 % with no
    failure counted, and a text file was met with NumPy's advice to load it as a pickle."""
    write(tmp_path / f"{scene_dir.name}.npy", truth.depth("left").shape)
    rows = evaluate_scenes([scene_dir], tmp_path)
    assert rows[0].failed and said in rows[0].reason, rows[0].reason
    assert "pickle" not in rows[0].reason


def test_the_estimate_rigkit_depth_help_writes_is_found(scene_dir, truth, tmp_path) -> None:
    """`rigkit depth ... --out out/scene-depth.npy` then `rigkit eval out/scene
    --depth-dir out`, as `rigkit depth --help` shows (issue 37)."""
    np.save(tmp_path / f"{scene_dir.name}-depth.npy", truth.depth("left"))
    [row] = evaluate_scenes([scene_dir], tmp_path)
    assert not row.failed and row.under_1 == pytest.approx(1.0)


def test_wrong_shape_is_an_input_error(truth, judged) -> None:
    gt = truth.depth("left")
    with pytest.raises(InputError, match="ground truth is"):
        depth_metrics(gt[:-1], gt, judged)


def test_change_metrics_split_static_moved_and_shadowed() -> None:
    truth = np.full((10, 10), 300.0)
    judged = np.ones((10, 10), bool)
    judged[:, 9] = False  # the right view does not see the last column
    moved = np.zeros((10, 10), bool)
    moved[:2] = True  # 20 moved pixels, 2 of them not judged: all 20 count
    shadow = np.zeros((10, 10), bool)
    shadow[8] = True  # 9 judged pixels under a changed shadow (10 minus the last column)
    est = truth * 1.002  # static pixels 0.2 % long
    est[0, :10] = truth[0, :10] * 1.05  # 10 moved pixels given a depth 5 % off ...
    est[1, :5] = np.nan  # ... 5 given none, 5 right
    est[8, :3] = truth[8, :3] * 1.02  # 3 shadowed pixels 2 % off
    c = change_metrics(est, truth, judged, moved, shadow)
    static = judged & ~moved & ~shadow  # rows 2-7 and 9, columns 0-8
    assert c.static_share == pytest.approx(static.sum() / judged.sum())
    assert c.static_under_1 == 1.0 and c.static_bias == pytest.approx(0.002)
    assert c.moved_share == pytest.approx(0.2)
    assert c.moved_density == pytest.approx(15 / 20) and c.moved_wrong == pytest.approx(10 / 20)
    assert c.shadow_share == pytest.approx(9 / judged.sum())
    assert c.shadow_under_1 == pytest.approx(6 / 9)


def test_textured_static_pixels_are_those_a_matching_window_away_from_plain_ones() -> None:
    # A plain wall (columns 30-39) beside textured ground: the estimate misses the 4
    # textured columns next to the wall, as a window-based matcher does.
    truth = np.full((60, 60), 300.0)
    plain = np.zeros((60, 60), bool)
    plain[:, 30:40] = True
    judged = ~plain
    est = truth.copy()
    est[:, 26:30] = np.nan
    none = np.zeros((60, 60), bool)
    c = change_metrics(est, truth, judged, none, none, plain)
    static = judged.sum()
    assert c.static_under_1 == pytest.approx(1 - 4 * 60 / static)
    clear = 60 * (60 - 10 - 2 * TEXTURE_MARGIN_PX)  # columns a window away from the wall
    assert c.textured_share == pytest.approx(clear / static)
    assert c.textured_under_1 == 1.0
    est[:, 5] = truth[:, 5] * 1.02  # a miss far from the wall counts
    c = change_metrics(est, truth, judged, none, none, plain)
    assert c.textured_under_1 == pytest.approx(1 - 60 / clear)


def test_table_and_csv_grow_only_for_scenes_where_the_world_moves(tmp_path) -> None:
    still = depth_metrics(np.full((4, 4), 300.0), np.full((4, 4), 300.0), np.ones((4, 4), bool),
                          "still")
    plain_text = format_table([still])
    assert "where the world moves" not in plain_text
    write_csv([still], tmp_path / "a.csv")
    header = (tmp_path / "a.csv").read_text().splitlines()[0]
    assert header == ("scene,judged_pixels,density,under_0_5,under_1,under_2,under_3,"
                      "median_bias,failed,reason,false_depth")
    moving = replace(still, scene="moving", changes=ChangeMetrics(
        0.9, 0.99, 0.001, 0.05, 0.8, 0.3, 0.02, 0.97, 0.8, 0.995))
    text = format_table([still, moving])
    first = format_table([still, replace(moving, changes=None)]).split("\nfailures")[0]
    assert text.startswith(first)  # the first table as it was
    assert "where the world moves" in text and "30.00" in text
    write_csv([still, moving], tmp_path / "b.csv")
    rows = (tmp_path / "b.csv").read_text().splitlines()
    assert rows[0].startswith(header + ",static_share,")
    assert rows[1].split(",")[-1] == "nan" and rows[2].split(",")[-3] == "0.97"
    assert rows[2].split(",")[-1] == "0.995" and "99.50" in text  # textured<1%


def test_a_moving_scene_is_scored_by_what_changed(tmp_path) -> None:
    params = SynthParams(width=320, height=240, n_movers=8, n_shadows=1)
    write_scene(generate_scene(params, 3), tmp_path / "moving")
    truth = load_scene(tmp_path / "moving")
    np.save(tmp_path / "moving.npy", truth.depth("left"))  # a perfect estimate
    (row,) = evaluate_scenes([tmp_path / "moving"], tmp_path)
    c = row.changes
    assert c is not None and 0 < c.moved_share < 0.5 and 0 < c.static_share < 1
    assert c.static_under_1 == 1.0 and c.moved_density == 1.0 and c.moved_wrong == 0.0


def test_flat_surfaces_are_not_judged_and_depth_there_is_false() -> None:
    truth = np.full((10, 10), 300.0)
    truth[0] = np.nan  # no surface (sky)
    flat = np.zeros((10, 10), bool)
    flat[1:3] = True  # a plain wall: nothing to match
    est = truth.copy()
    est[1] = 300.0  # a depth given on the wall (from its neighbours)
    est[2] = np.nan
    m = depth_metrics(est, truth, np.isfinite(truth) & ~flat, "wall", flat)
    assert m.judged_pixels == 70 and m.under_1 == 1.0
    assert m.false_depth == pytest.approx(10 / 30)  # the wall row of 30 nothing-to-match
