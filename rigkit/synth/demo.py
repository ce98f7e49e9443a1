"""``rigkit field --demo``: the whole field flow with no hardware.

A small synthetic scene (:mod:`rigkit.synth`) is rendered into a temporary folder; a
simulated camera writes its frames one at a time into a watched "card" folder, in
pieces as a real card or tethering tool does; a simulated TruPulse
(:mod:`rigkit.rangefinder.sim`) answers with the scene's true range at the marked pixel
plus 5 cm of noise.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from rigkit.core.files import write_text
from rigkit.core.yamlfile import dump_yaml
from rigkit.synth import SynthParams, generate_scene, load_scene, write_scene
from rigkit.synth.session import rig_for_scene

DEMO_SIZE = (1536, 1152)
"""Demo frame size (width, height), px, that of the bundled example: small, so the checks
and processing take seconds, yet large enough that at ``DEMO_RANGE_M`` the disparity
offset the run measures stays under the 0.3 % of depth a "done" verdict allows (at
1024x768 and 250 m it was 0.72 %, and the demo's verdict said "capture again")."""
DEMO_RANGE_M = 200.0
"""The demo scene's distance, m (``rigkit rig check`` on the demo's rig.yaml: 2-sigma
depth error 0.6 % there; the run on seed 7 reports 0.20 % of depth, 1 sigma)."""
DEMO_SEED = 7
LASER_NOISE_M = 0.05
SHOT_PIECES = 4


@dataclass(frozen=True)
class Demo:
    """The demo's folders: ``scene`` (rendered frames and ground truth), ``card`` (the
    watched folder frames arrive in), ``capture`` (sessions), ``rig`` (its profile)."""

    root: Path
    seed: int = DEMO_SEED
    shot_s: float = 0.8
    """Seconds between the simulated camera's pieces of a file and the laser's shots."""

    @property
    def scene(self) -> Path:
        return self.root / "scene"

    @property
    def card(self) -> Path:
        return self.root / "card"

    @property
    def capture(self) -> Path:
        return self.root / "capture"

    @property
    def rig(self) -> Path:
        return self.root / "rig.yaml"

    @property
    def session(self) -> Path:
        return self.capture / "demo"

    def shoot(self, position: str, number: int) -> Path:
        """Write ``position``'s rendered frame into the card as ``DSCN<number>.PNG`` in
        pieces, ``shot_s / 8`` seconds apart (blocking). Returns the file."""
        data = (self.scene / f"{position}.png").read_bytes()
        target = self.card / f"DSCN{number:04d}.PNG"
        step = math.ceil(len(data) / SHOT_PIECES)
        with target.open("wb") as handle:
            for start in range(0, len(data), step):
                handle.write(data[start:start + step])
                handle.flush()
                time.sleep(self.shot_s / 8)
        return target

    def laser_url(self, pixel: tuple[float, float]) -> str:
        """A simulated TruPulse aimed at ``pixel`` of the left view: it fires every
        ``shot_s`` seconds and reports the true range there."""
        return (f"sim://trupulse?distance={true_range_m(self.scene, pixel):.3f}"
                f"&noise={LASER_NOISE_M}&interval={self.shot_s:g}&inclination=0.5"
                f"&seed={self.seed}")


def true_range_m(scene: Path, pixel: tuple[float, float]) -> float:
    """Distance from the left camera's centre to the scene point seen at ``pixel``, m
    (the nearest valid ground-truth depth in a 7 px window)."""
    truth = load_scene(scene)
    depth = truth.depth("left")
    u, v = round(pixel[0]), round(pixel[1])
    window = depth[max(v - 3, 0):v + 4, max(u - 3, 0):u + 4]
    z = float(np.nanmedian(window)) if np.isfinite(window).any() else float(np.nanmax(depth))
    left = truth.cameras["left"]
    ray = left.rays(np.array([float(pixel[0])]), np.array([float(pixel[1])]))[0]
    return float(np.linalg.norm(ray * z - left.C))


def demo_params(size: tuple[int, int]) -> SynthParams:
    """The demo scene's settings at ``size`` (width, height) px: the synthetic defaults
    at ``DEMO_RANGE_M``, with principal points off centre by as much of the frame as
    the defaults' 30 px are of 4608 px (a smaller sensor of the same make, not a 30 px
    offset on a 1536 px frame, whose bend of the back view alone would leave the
    disparity offset 0.37 % of depth)."""
    defaults = SynthParams()
    return SynthParams(width=size[0], height=size[1], distance_m=DEMO_RANGE_M,
                       max_pp_offset_px=defaults.max_pp_offset_px * size[0] / defaults.width)


def prepare_demo(root: Path, seed: int = DEMO_SEED, size: tuple[int, int] = DEMO_SIZE,
                 shot_s: float = 0.8) -> Demo:
    """Render the demo scene under ``root`` and write its rig profile; returns the folders."""
    demo = Demo(root, seed, shot_s)
    scene = generate_scene(demo_params(size), seed)
    write_scene(scene, demo.scene)
    demo.card.mkdir(parents=True, exist_ok=True)
    demo.capture.mkdir(parents=True, exist_ok=True)
    write_text(demo.rig, dump_yaml(rig_for_scene(scene)))
    return demo
