"""A synthetic scene as a complete capture session, with simulated laser targets.

The scene's images become the session's frames (in ``raw/``), its exact geometry
becomes the rig profile (``rig.yaml``), and targets are picked where the ground truth is
locally flat and seen by the right camera, as an operator would aim a laser. Each
target gets simulated readings: the true range from the left camera's centre plus
Gaussian noise. ``scene.yaml`` and ``ground_truth/`` stay, so ``rigkit eval`` works too.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from rigkit.capture import (
    LaserReading,
    Session,
    add_frame,
    add_target,
    create_session,
    load_session,
    utc_now,
)
from rigkit.core.files import write_text
from rigkit.core.yamlfile import dump_yaml
from rigkit.synth.evaluate import visible_in_right
from rigkit.synth.io import VIEWS, check_out_folder, frame_name, load_scene, write_scene
from rigkit.synth.placement import Placement, place_session
from rigkit.synth.scene import Scene

RIG_FILE = "rig.yaml"
FLATNESS = 0.002  # targets need depth within 0.2 % across their window


def _lens(distortion: tuple[float, ...]) -> dict[str, Any]:
    """The profile's ``distortion`` entry for a lens that has one."""
    if not any(distortion):
        return {}
    return {"distortion": dict(zip(("k1", "k2", "p1", "p2", "k3"), distortion, strict=True))}


def rig_for_scene(scene: Scene) -> dict[str, Any]:
    """A rig profile (YAML data) describing the scene's cameras exactly.

    The principal point is left unknown, as on a real rig: the scene's are offset at
    random and the pipeline does not need them.
    """
    p = scene.params
    return {
        "version": 1,
        "name": f"synthetic-seed-{scene.seed}",
        "nominal_range_m": p.distance_m,
        "camera": {
            "model": "synthetic pinhole",
            "resolution": [p.width, p.height],
            "focal_length": {"px": p.focal_px, "tolerance_fraction": 0.0},
            **_lens(p.distortion),
        },
        "baselines": {
            "C_lr": {"value_m": p.baseline_lr_m, "tolerance_m": 0.0},
            "C_lb": {"value_m": p.baseline_lb_m, "tolerance_m": 0.0},
        },
        "back_offset": {"right_m": p.back_side_m, "up_m": p.back_up_m},
        "rangefinder": {
            "protocol": "manual",
            "offset": {"right_m": 0.0, "up_m": 0.0, "forward_m": 0.0},
        },
        "notes": f"Rendered by rigkit synth, seed {scene.seed}.",
    }


FULL_WIDTH_PX = 4608  # the paper's 16 MP frames, the scale field figures are quoted at


def conditions_note(scene: Scene) -> str:
    """One paragraph, for a synthetic session's notes: the seed and what the capture
    was rendered with, the shimmer also at the full-resolution pixel scale (the angle
    it is), so that a reader can tell what air and what range the session stands for."""
    p = scene.params
    full = FULL_WIDTH_PX / p.width
    parts = [
        f"synthetic scene, seed {scene.seed}: {p.width}x{p.height} px over {p.hfov_deg:g} deg "
        f"(one px is {full:.1f} px of a {FULL_WIDTH_PX} px frame), scene at {p.distance_m:g} m",
        f"bursts of {p.burst}" if p.burst > 1 else "one frame per position",
    ]
    if p.shimmer_px:
        parts.append(
            f"heat shimmer {p.shimmer_px:g} px RMS ({p.shimmer_px * full:.2f} px at "
            f"{FULL_WIDTH_PX} px; {p.shimmer_spectrum}, over {p.shimmer_corr_px:g} px)"
        )
    if p.sky:
        parts.append(f"sky over {100 * p.sky:.0f} % of the height, haze {p.haze_m:g} m")
    if any(p.distortion):
        parts.append(f"lens k1 {p.distortion[0]:g} (given in rig.yaml)")
    parts.append(f"principal points within +-{p.max_pp_offset_px:g} px of the centre")
    return "; ".join(parts)


def write_synthetic_session(
    scene: Scene,
    out_dir: Path,
    *,
    n_targets: int = 5,
    laser_sigma_m: float = 0.05,
    seed: int = 0,
    progress: Callable[[str, float], None] | None = None,
    placement: Placement | None = None,
) -> Session:
    """Render ``scene`` into ``out_dir`` (missing or empty) as a session with
    ``n_targets`` laser targets, placed on the map by ``placement`` if given
    (:func:`rigkit.synth.placement.place_session`)."""
    check_out_folder(out_dir, new=True)
    write_scene(scene, out_dir, progress)
    session = session_from_rendered(
        scene, out_dir, n_targets=n_targets, laser_sigma_m=laser_sigma_m, seed=seed
    )
    if placement is None:
        return session
    place_session(out_dir, placement)
    return load_session(out_dir)


def session_from_rendered(
    scene: Scene,
    out_dir: Path,
    *,
    n_targets: int = 5,
    laser_sigma_m: float = 0.05,
    seed: int = 0,
    frame_suffix: str = ".png",
) -> Session:
    """Turn a scene folder ``rigkit synth`` wrote for ``scene`` into a session.

    Its rendered images (``left.png`` ..., or another ``frame_suffix`` such as ``.dng``
    for renderings stored as RAW) move into ``raw/`` (copied, then the originals
    removed).
    """
    write_text(out_dir / RIG_FILE, dump_yaml(rig_for_scene(scene)))
    session = create_session(out_dir, out_dir / RIG_FILE, notes=conditions_note(scene))
    for view in VIEWS:
        burst = [out_dir / f"{view}{frame_suffix}"]
        burst += [out_dir / frame_name(view, k) for k in range(1, scene.params.burst)]
        for rendered in burst:
            session = add_frame(session, view, rendered, burst=True,
                                origin=f"rendered by rigkit synth, seed {scene.seed}")
            rendered.unlink()  # rendered by us a moment ago; the copy in raw/ is the frame
    truth = load_scene(out_dir)
    rng = np.random.default_rng(seed)
    window = _window_px(scene.params.width)
    for i, (u, v, true_range) in enumerate(pick_targets(truth, n_targets, window, rng)):
        reading = LaserReading(
            slope_distance_m=round(true_range + rng.normal(0.0, laser_sigma_m), 3),
            time_utc=utc_now(),
            source="simulated",
        )
        session = add_target(session, f"T{i + 1}", (u, v), window_px=window,
                             readings=[reading], note=f"true range {true_range:.3f} m")
    return session


def _window_px(width: int) -> int:
    """About 1/128 of the image width, odd, at least 5 px."""
    side = max(5, width // 128)
    return side if side % 2 else side + 1


def pick_targets(
    truth: Any, count: int, window_px: int, rng: np.random.Generator
) -> list[tuple[int, int, float]]:
    """Up to ``count`` (u, v, true range in m) spread over the left image.

    Candidates are pixels whose window is fully seen by the right camera and flat
    within :data:`FLATNESS`; the first is drawn at random, each next is the candidate
    farthest from those chosen. The range is from the left camera's centre.
    """
    z = truth.depth("left")
    seen = visible_in_right(truth)
    half = window_px // 2
    height, width = z.shape
    step = max(window_px, min(width, height) // 40)
    candidates = []
    for v in range(height // 10, height - height // 10, step):
        for u in range(width // 10, width - width // 10, step):
            patch = z[v - half : v + half + 1, u - half : u + half + 1]
            if not seen[v - half : v + half + 1, u - half : u + half + 1].all():
                continue
            if np.ptp(patch) <= FLATNESS * float(np.median(patch)):
                candidates.append((u, v))
    if not candidates or count < 1:
        return []
    points = np.array(candidates, float)
    chosen = [int(rng.integers(len(points)))]
    while len(chosen) < min(count, len(points)):
        distance = np.min(
            np.linalg.norm(points[:, None] - points[chosen][None], axis=2), axis=1
        )
        chosen.append(int(np.argmax(distance)))
    left = truth.cameras["left"]
    out = []
    for index in chosen:
        u, v = candidates[index]
        ray = left.rays(np.array([float(u)]), np.array([float(v)]))[0]
        point = ray * float(z[v, u])  # world frame = left camera frame
        out.append((u, v, float(np.linalg.norm(point - left.C))))
    return out
