"""The run's information as export reads it from depth.json / D.json, in one place: the
lens every pixel is back-projected through, where it comes from, and one line naming
the key of a value that is not one."""

from __future__ import annotations

from pathlib import Path

import pytest

from rigkit.errors import InputError
from rigkit.export.runinfo import run_info

SIZE = (800, 600)
META = {
    "run_id": "20260412T090000Z-0001", "time_utc": "2026-04-12T09:00:00Z",
    "rigkit_version": "0.1.0",
    "rig": {"name": "p1000", "focal_px": 5000.0, "baseline_lr_m": 2.0, "baseline_lb_m": 2.0,
            "distortion_k1_k2_p1_p2_k3": [0.4, 0, 0, 0, 0], "one_camera": False,
            "principal_points_px": [[2.0, -1.0], [0.0, 0.0], [0.0, 0.0]]},
    "distortion_k1_k2_p1_p2_k3": [0.45, -0.1, 0.0, 0.0, 0.0],
    "lens_fit": {"k1_k2_p1_p2_k3": [0.45, -0.1, 0, 0, 0],
                 "centres_px": {"left": [3.25, -1.5], "right": [0, 0], "back": [1, 1]}},
    "settings": {"distortion_terms": 2}, "warnings": ["a warning"],
    "offset_depth_error_fraction": 0.002,
}


def test_a_fitted_lens_is_the_one_the_run_used() -> None:
    run = run_info(META, SIZE, Path("depth.json"))
    assert run.lens.distortion == (0.45, -0.1, 0.0, 0.0, 0.0)  # the lens the depth went through
    assert run.lens.shift == (3.25, -1.5) and run.lens.focal_px == 5000.0
    assert run.lens.size == SIZE and run.lens_source == "fitted from the three views by the run"
    assert (run.run_id, run.rig, run.warnings) == (META["run_id"], "p1000", ("a warning",))
    assert run.as_dict()["lens"]["centre_shift_px"] == [3.25, -1.5]


def test_without_a_fit_the_rig_profiles_lens_and_principal_point() -> None:
    meta = {**META, "lens_fit": None, "distortion_k1_k2_p1_p2_k3": [0.4, 0, 0, 0, 0]}
    run = run_info(meta, SIZE, Path("depth.json"))
    assert run.lens.shift == (2.0, -1.0) and run.lens.distortion[0] == 0.4
    assert run.lens_source == "the rig profile's"


def test_older_metadata_falls_back_on_what_it_has() -> None:
    """A D.json from before the lens was recorded: a pinhole at its principal point;
    from before that, at the image centre."""
    old = {"rig": {"name": "bench", "focal_px": 4000.0},
           "left_camera_px": {"f": 4000.0, "cx": 410.5, "cy": 290.0}}
    run = run_info(old, SIZE, Path("d.json"))
    assert run.lens.shift == (11.0, -9.5) and run.lens.pinhole
    assert run.lens_source.startswith("a pinhole at the recorded principal point")
    del old["left_camera_px"]
    assert run_info(old, SIZE, Path("d.json")).lens.identity


@pytest.mark.parametrize(("change", "message"), [
    ({"distortion_k1_k2_p1_p2_k3": [0.4, "x", 0, 0, 0]},
     "d.json: distortion_k1_k2_p1_p2_k3 is [0.4, 'x', 0, 0, 0], not 5 finite numbers"),
    ({"lens_fit": {"centres_px": {"right": [0, 0]}}},
     "d.json: lens_fit.centres_px.left is None, not 2 finite numbers"),
    ({"lens_fit": "yes"}, "d.json: lens_fit is not a mapping"),
    ({"rig": {"name": "x", "focal_px": "5000 px"}},
     "d.json: rig.focal_px is '5000 px', not a finite number"),
    ({"rig": {"name": "x"}, "left_camera_px": None},
     "d.json: no rig focal length (not written by rigkit depth?)"),
])
def test_a_value_that_is_not_one_is_named(change: dict, message: str) -> None:
    with pytest.raises(InputError) as error:
        run_info({**META, **change}, SIZE, Path("d.json"))
    assert str(error.value) == message
