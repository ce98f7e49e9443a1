"""Public names imported on first use, SciPy imported where it is used, and imports in a
thread of their own (rigkit.core.lazy, issue 38): reading frames must not wait for the
pipeline's optimisers."""

from __future__ import annotations

import json
import subprocess
import sys
import time

import pytest

from rigkit.core import lazy

# Each entry imports one module in a fresh interpreter and reports which heavy modules
# came with it.
PROBE = """
import json, sys
import {module}
print(json.dumps(sorted(m for m in sys.modules if m.split(".")[0] in ("scipy", "skimage")
                        or m.startswith(("rigkit.pipeline.estimate", "rigkit.rig.budget")))))
"""


@pytest.mark.parametrize(("module", "frames_side"), [
    ("rigkit.capture.frames", True), ("rigkit.rig.profile", True),
    ("rigkit.batch.depthrun", False), ("rigkit.pipeline.estimate", False)])
def test_reading_frames_imports_no_optimiser(module: str, frames_side: bool) -> None:
    out = subprocess.run([sys.executable, "-c", PROBE.format(module=module)],
                         capture_output=True, text=True, check=True, timeout=120).stdout
    loaded = json.loads(out)
    assert "scipy.optimize" not in loaded  # imported while the frames decode, or when used
    if frames_side:  # nothing of the pipeline's stages or the error budget behind them
        assert "rigkit.pipeline.estimate" not in loaded and "rigkit.rig.budget" not in loaded


def test_exports_give_each_name_from_its_module() -> None:
    import rigkit.pipeline as pipeline
    from rigkit.pipeline.estimate import estimate_depth
    from rigkit.pipeline.rig import RigGeometry

    assert pipeline.estimate_depth is estimate_depth
    assert pipeline.RigGeometry is RigGeometry
    with pytest.raises(AttributeError, match="no attribute 'nothing'"):
        pipeline.nothing  # noqa: B018


@pytest.mark.parametrize("package", ["rigkit.batch", "rigkit.capture", "rigkit.export",
                                     "rigkit.pipeline", "rigkit.rig", "rigkit.synth"])
def test_every_public_name_resolves(package: str) -> None:
    module = __import__(package, fromlist=["__all__"])
    for name in module.__all__:
        assert getattr(module, name) is not None, f"{package}.{name}"


def test_function_imports_on_first_call(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delitem(sys.modules, "colorsys", raising=False)
    to_hls = lazy.function("colorsys", "rgb_to_hls")
    assert "colorsys" not in sys.modules
    assert to_hls(1.0, 0.0, 0.0) == (0.0, 0.5, 1.0)
    assert "colorsys" in sys.modules and to_hls.__name__ == "rgb_to_hls"


def test_preload_imports_in_another_thread(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delitem(sys.modules, "colorsys", raising=False)
    lazy.preload("colorsys", "no_such_module_anywhere")
    deadline = time.monotonic() + 30
    while "colorsys" not in sys.modules and time.monotonic() < deadline:
        time.sleep(0.01)
    assert "colorsys" in sys.modules  # and the missing one is left to its user to report
