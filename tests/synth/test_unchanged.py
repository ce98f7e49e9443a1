"""What moves, facades and shimmer spectra are off by default: every seed renders as it
did before they existed, and a scene folder records them when they are on."""

from __future__ import annotations

import hashlib
from dataclasses import replace
from pathlib import Path

import cv2
import numpy as np

from rigkit.synth import SynthParams, generate_scene, load_scene, write_scene
from rigkit.synth.render import expose, render_view

EXAMPLE = Path(__file__).resolve().parents[2] / "capture" / "example"
# sha256 over the three frames and depth maps of seed 5 at 320x240 (the paper's protocol
# otherwise), rendered by main at 740e63c, before any of them.
DEFAULT_SHA256 = "bf3bea50a1557f647a5698bc1a918b0e134de94a9babab6361e67bb19ff29d90"


def test_the_paper_protocol_renders_as_before() -> None:
    scene = generate_scene(SynthParams(width=320, height=240), 5)
    digest = hashlib.sha256()
    for view in ("left", "right", "back"):
        radiance, depth = render_view(scene, view)
        digest.update(expose(scene, view, radiance).tobytes())
        digest.update(depth.tobytes())
    assert digest.hexdigest() == DEFAULT_SHA256


def test_the_bundled_example_renders_as_committed() -> None:
    # Seed 7 at 1536x1152 with sky, haze, gaussian shimmer, a lens and bursts of five.
    truth = load_scene(EXAMPLE)
    scene = generate_scene(truth.params, truth.seed)
    radiance, depth = render_view(scene, "left")
    assert np.array_equal(depth, truth.depth("left"), equal_nan=True)
    frames = truth.frame_paths("left")
    assert len(frames) == 5
    for k, path in enumerate(frames):
        committed = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
        assert np.array_equal(expose(scene, "left", radiance, frame=k), committed)


def test_scene_folder_records_the_world_and_its_masks(tmp_path) -> None:
    params = replace(SynthParams(width=160, height=120), n_movers=4, n_shadows=1,
                     shadow_drift_m=4.0, n_facades=1, shimmer_px=0.2,
                     shimmer_spectrum="vonkarman", shimmer_outer_px=300.0)
    write_scene(generate_scene(params, 3), tmp_path / "busy")
    truth = load_scene(tmp_path / "busy")
    assert truth.params == params
    changes = truth.changes()
    assert changes is not None
    for mask in changes:
        assert mask.shape == (120, 160) and mask.dtype == bool
    write_scene(generate_scene(SynthParams(width=160, height=120), 3), tmp_path / "still")
    assert load_scene(tmp_path / "still").changes() is None
    names = {p.name for p in (tmp_path / "still" / "ground_truth").iterdir()}
    assert names == {"depth_left.npy", "depth_right.npy", "depth_back.npy", "flat_left.npy",
                     ".rigkit-outputs"}  # and the ledger of what rigkit wrote there
