"""One ``rigkit depth`` run on the shared scene's PNGs, read by the tests that check its
outputs, so that the suite computes that depth once."""

from __future__ import annotations

import contextlib
import io
from pathlib import Path

import pytest

from rigkit.cli import main
from rigkit.synth import SceneTruth


@pytest.fixture(scope="session")
def scene_depth(scene_dir: Path, truth: SceneTruth,
                tmp_path_factory: pytest.TempPathFactory) -> tuple[int, Path, str]:
    """``rigkit depth`` of ``scene_dir``'s left, right and back PNGs with the focal length
    and both baselines as flags, and --preview: its exit code, its folder (d.npy and its
    sidecars; read-only) and what it printed."""
    out = tmp_path_factory.mktemp("scene-depth")
    frames = [str(scene_dir / f"{v}.png") for v in ("left", "right", "back")]
    flags = ["--focal-px", str(truth.focal_px), "--baseline-lr", "2", "--baseline-lb", "2"]
    printed = io.StringIO()
    with contextlib.redirect_stdout(printed):
        code = main(["depth", *frames, "--out", str(out / "d.npy"), "--quiet", *flags,
                     "--preview"])
    return code, out, printed.getvalue()
