"""Shared fixtures: one small synthetic scene with ground truth, and the pipeline's
result on it, computed once per test session."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import pytest

from rigkit.pipeline import DepthResult, RigGeometry, estimate_depth
from rigkit.pipeline.images import load_grey
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
def processed_session(synth_session: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """``synth_session`` after one ``rigkit process`` run (read-only, like it)."""
    import shutil

    from rigkit.process import process_session

    out = tmp_path_factory.mktemp("processed") / "seed-3"
    shutil.copytree(synth_session, out)
    process_session(out, "20260101T000000Z-0001")
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
