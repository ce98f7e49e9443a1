"""The run as export takes it from its record (capture/results.RunRecord, the one reader
of depth.json / D.json): the lens every pixel is back-projected through, the left view's
as the run took it out, and where it comes from."""

from __future__ import annotations

from pathlib import Path

import pytest

from rigkit.capture.results import read_record, session_record
from rigkit.export.runinfo import FITTED, PROFILE, RunInfo
from rigkit.pipeline.rig import RigGeometry
from rigkit.pipeline.settings import PipelineSettings
from tests.conftest import make_record

SIZE = (800, 600)
CENTRE = ((SIZE[0] - 1) / 2, (SIZE[1] - 1) / 2)
FITTED_RUN = make_record(
    run_id="20260412T090000Z-0001", rig_name="p1000", image_size_px=SIZE,
    rig=RigGeometry(5000.0, 2.0, 2.0, (0.4, 0.0, 0.0, 0.0, 0.0),
                    principal_points_px=((2.0, -1.0), (0.0, 0.0), (0.0, 0.0))),
    settings=PipelineSettings(distortion_terms=2),
    lens=(0.45, -0.1, 0.0, 0.0, 0.0),
    left_camera_px=(5000.0, CENTRE[0] + 3.25, CENTRE[1] - 1.5),
    warnings=("a warning",), offset_depth_fraction=0.002)
"""A run that fitted the lens (two terms) and the left view's centre."""


def test_a_fitted_lens_is_the_one_the_run_used() -> None:
    run = RunInfo.of(FITTED_RUN)
    assert run.lens.distortion == (0.45, -0.1, 0.0, 0.0, 0.0)  # not the profile's 0.4
    assert run.lens.shift == (3.25, -1.5)  # the fitted centre, not the profile's (2, -1)
    assert run.lens.focal_px == 5000.0 and run.lens.size == SIZE
    assert run.lens_source == FITTED
    assert (run.run_id, run.rig, run.offset_depth_fraction) == (FITTED_RUN.run_id, "p1000",
                                                               0.002)
    data = run.as_dict()
    assert data["lens"]["centre_shift_px"] == [3.25, -1.5]
    assert data["warnings"] == ["a warning"] and data["settings"]["distortion_terms"] == 2
    assert data["rig_values"] == {"focal_px": 5000.0, "baseline_lr_m": 2.0,
                                  "baseline_lb_m": 2.0, "one_camera": False}


def test_without_a_fit_the_rig_profiles_lens() -> None:
    record = make_record(settings=PipelineSettings(distortion_terms=0),
                         lens=(0.4, 0.0, 0.0, 0.0, 0.0))
    assert RunInfo.of(record).lens_source == PROFILE
    plain = RunInfo.of(make_record(settings=PipelineSettings(distortion_terms=0)))
    assert plain.lens_source == f"{PROFILE}, without distortion" and plain.lens.identity


def test_the_lens_survives_the_record_written_and_read(tmp_path: Path) -> None:
    path = tmp_path / "d.json"
    path.write_text(FITTED_RUN.to_json())
    assert read_record(path).left_lens == FITTED_RUN.left_lens


@pytest.mark.slow
def test_a_processed_runs_left_camera_is_the_lens_fits_left_centre(
        processed_small: Path) -> None:
    """``rigkit process`` records the centre its lens fit gave the left view (depth.json's
    diagnostics say it to 0.01 px), so export and the laser comparison back-project
    through the lens the depth went through."""
    record = session_record(processed_small)
    assert record is not None
    fit = record.details["lens_fit"]
    assert fit is not None  # the pipeline fits the lens by default
    shift = record.left_lens.shift
    assert shift == pytest.approx(fit["centres_px"]["left"], abs=0.006)
    assert record.left_lens.distortion == tuple(fit["k1_k2_p1_p2_k3"])
