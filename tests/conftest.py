"""Shared fixtures: one small synthetic scene with ground truth, and the pipeline's
result on it, computed once per test session."""

from __future__ import annotations

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
