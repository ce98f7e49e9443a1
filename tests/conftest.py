"""Shared fixtures: one small synthetic scene with ground truth, and the pipeline's
result on it, computed once per test session."""
# ruff: noqa: E402 (the thread limits below must come before numpy's first import)

from __future__ import annotations

import os

# One BLAS thread per test process, set before numpy is first imported (here, through
# rigkit): with OpenBLAS's own threads the lens fit's many small solves and SVDs took
# 10x as long on a 2-core machine that was busy with anything else (the threads spin
# waiting for a core), e.g. 37 s instead of 3.6 s for tests/pipeline/test_distortion.py.
# The batch pool's worker processes inherit it. Under pytest-xdist (scripts/test.sh runs
# `pytest -n auto`) the workers already share the cores, so OpenCV gets one thread each too.
# Any of these set in the environment wins.
for _name in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_name, "1")
if "PYTEST_XDIST_WORKER" in os.environ:
    os.environ.setdefault("OPENCV_FOR_THREADS_NUM", "1")

import math
from collections.abc import Callable
from dataclasses import replace
from pathlib import Path

import pytest

from rigkit.capture.comparisons import (
    LOG_NAME,
    STATUS_NO_ESTIMATE,
    STATUS_OK,
    Comparison,
    append_rows,
)
from rigkit.capture.model import Session
from rigkit.capture.results import RecordedFrame, RunRecord
from rigkit.imagefile.decode import load_grey
from rigkit.pipeline import DepthResult, RigGeometry, estimate_depth
from rigkit.pipeline.settings import PipelineSettings
from rigkit.synth import SceneTruth, SynthParams, generate_scene, load_scene, write_scene

SMALL = SynthParams(width=960, height=720)


@pytest.fixture(scope="session")
def scene_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("scene") / "seed-3"
    write_scene(generate_scene(SMALL, seed=3), out)
    return out


@pytest.fixture(scope="session")
def truth(scene_dir: Path) -> SceneTruth:
    return load_scene(scene_dir)


@pytest.fixture(scope="session")
def images(truth: SceneTruth) -> dict:
    return {v: load_grey(truth.image_path(v)) for v in ("left", "right", "back")}


@pytest.fixture(scope="session")
def rig(truth: SceneTruth) -> RigGeometry:
    return RigGeometry(truth.focal_px, truth.baseline_lr_m, truth.baseline_lb_m)


@pytest.fixture(scope="session")
def result(images: dict, rig: RigGeometry) -> DepthResult:
    return estimate_depth(images["left"], images["right"], images["back"], rig)


@pytest.fixture(scope="session")
def synth_session(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A complete capture session (PNG frames, 5 simulated laser targets) of seed 3.

    Treat it as read-only: copy it (``copy_session``) before changing it.
    """
    from rigkit.synth.session import write_synthetic_session

    out = tmp_path_factory.mktemp("sessions") / "seed-3"
    write_synthetic_session(generate_scene(SMALL, seed=3), out, n_targets=5, seed=3)
    return out


@pytest.fixture(scope="session")
def small_session(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """``synth_session`` at 384x288 px, for tests of how sessions are run (worker pools,
    clusters, failures) whose assertions do not depend on the frames' size: it renders in
    a quarter and processes in half of ``synth_session``'s time. Read-only like it."""
    from rigkit.synth.session import write_synthetic_session

    out = tmp_path_factory.mktemp("sessions") / "small-seed-3"
    write_synthetic_session(generate_scene(replace(SMALL, width=384, height=288), seed=3),
                            out, n_targets=5, seed=3)
    return out


@pytest.fixture(scope="session")
def processed_session(synth_session: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """``synth_session`` after one ``rigkit process`` run (read-only, like it)."""
    import shutil

    from rigkit.batch import process_session

    out = tmp_path_factory.mktemp("processed") / "seed-3"
    shutil.copytree(synth_session, out)
    process_session(out, "20260101T000000Z-0001")
    return out


@pytest.fixture(scope="session")
def processed_small(small_session: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """``small_session`` after one ``rigkit process`` run (read-only, like it): for
    tests of what a run leaves in a session rather than of its depth."""
    import shutil

    from rigkit.batch import process_session

    out = tmp_path_factory.mktemp("processed") / "small-seed-3"
    shutil.copytree(small_session, out)
    process_session(out, "20260101T000000Z-0002")
    return out


def copy_session(
    source: Path, folder: Path, name: str | None = None, edit: Callable | None = None
) -> Path:
    """A private copy of a session fixture to change in one test; ``edit(data)`` changes
    its session.yaml (as parsed YAML) in place, bypassing rigkit's own checks."""
    import shutil

    import yaml

    out = folder / (name or source.name)
    shutil.copytree(source, out)
    if edit is not None:
        data = yaml.safe_load((out / "session.yaml").read_text())
        edit(data)
        (out / "session.yaml").write_text(yaml.safe_dump(data))
    return out


def make_record(session: Session | None = None, **changes: object) -> RunRecord:
    """A run's record as rigkit writes it (:class:`rigkit.capture.results.RunRecord`):
    a 400x300 map of a rig of f 4000 px and 2 m baselines or, given a ``session``, of
    its frames, rig (and its lens) and targets as they are; with ``changes`` to its
    fields."""
    made = {} if session is None else {
        "frames": {pos: tuple(RecordedFrame(f.file, f.sha256) for f in burst)
                   for pos, burst in session.bursts.items()},
        "rig": session.rig().geometry(), "settings": session.rig().pipeline_settings(),
        "lens": session.rig().geometry().distortion, "targets": session.targets}
    record = RunRecord(frames={}, rig=RigGeometry(4000.0, 2.0, 2.0),
                       settings=PipelineSettings(), rig_name="synthetic",
                       image_size_px=(400, 300), left_camera_px=(4000.0, 199.5, 149.5),
                       lens=(0.0,) * 5, burst_length=1, median_depth_m=300.0,
                       offset_px=0.4, offset_sigma_px=0.05, offset_depth_fraction=0.001)
    return replace(record, **{**made, **changes})  # type: ignore[arg-type]


def rig_file(folder: Path, size: tuple[int, int], base: str = "synthetic.yaml",
             name: str = "rig.yaml") -> Path:
    """rigs/``base`` for frames of ``size`` (width, height) px, written into ``folder``:
    the same view, so a focal length given in px scales with the width."""
    import yaml

    from rigkit.rig import load_rig, rig_to_dict

    root = Path(__file__).resolve().parents[1]
    data = rig_to_dict(load_rig(root / "rigs" / base))
    focal = data["camera"]["focal_length"]
    if "px" in focal:
        focal["px"] *= size[0] / data["camera"]["resolution"][0]
    data["camera"]["resolution"] = list(size)
    path = folder / name
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    return path


# --------------------------------------------------------------------------- comparisons

OLD_RUN, NEW_RUN = "20261122T090000Z", "20261123T100000Z"


def make_row(
    target: str,
    laser: float,
    error_pct: float,
    *,
    session: str = "field-1",
    run: str = NEW_RUN,
    status: str = STATUS_OK,
    sigma: float = 0.5,
) -> Comparison:
    ok = status == STATUS_OK
    estimate = laser * (1 + error_pct / 100) if ok else math.nan
    return Comparison(
        run_id=run,
        time_utc="2026-11-23T10:00:00Z",
        session=session,
        target=target,
        u=1000.0,
        v=800.0,
        window_px=31,
        laser_range_m=laser,
        laser_readings=3 if math.isfinite(laser) else 0,
        laser_spread_m=0.05,
        estimate_range_m=estimate,
        estimate_sigma_m=sigma if ok else math.nan,
        valid_fraction=0.95 if ok else 0.0,
        error_m=estimate - laser,
        error_pct=100 * (estimate - laser) / laser,
        status=status,
    )


def make_log(root: Path, name: str, *runs: list[Comparison]) -> Path:
    """A session folder whose log gets one append per run, as `rigkit process` does."""
    folder = root / name
    folder.mkdir(parents=True, exist_ok=True)
    for rows in runs:
        append_rows(folder / LOG_NAME, rows)
    return folder


@pytest.fixture
def two_runs(tmp_path: Path) -> Path:
    old = [make_row(t, 300.0, 2.0, run=OLD_RUN) for t in ("T1", "T2")]
    new = [
        make_row("T1", 250.0, 1.0),
        make_row("T2", 350.0, -2.0),
        make_row("T3", 450.0, 0.5),
        make_row("T4", 420.0, 0.0, status=STATUS_NO_ESTIMATE),
    ]
    return make_log(tmp_path, "field-1", old, new)
