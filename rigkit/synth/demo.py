"""``rigkit field --demo``: the whole field flow with no hardware.

A small synthetic scene (:mod:`rigkit.synth`) is rendered into a temporary folder, with a
burst of frames per position under heat shimmer; a simulated camera writes the burst's
frames one at a time into a watched "card" folder, in pieces as a real card or tethering
tool does; a simulated TruPulse (:mod:`rigkit.rangefinder.sim`) answers with the scene's
true range at the marked pixel plus 5 cm of noise, and the azimuth and inclination of
that pixel's line of sight for a camera aimed at ``DEMO_AZIMUTH_DEG``, so that the
demo's export is georeferenced from the tripod's position the demo session records.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from rigkit.capture import create_session, is_session
from rigkit.capture.positioning import set_tripod_position
from rigkit.capture.session import utc_now
from rigkit.capture.tripod import TripodPosition
from rigkit.core.files import write_text
from rigkit.core.yamlfile import dump_yaml
from rigkit.geometry import focal_from_fov
from rigkit.rig.bursts import default_shimmer
from rigkit.synth import SynthParams, generate_scene, load_scene, write_scene
from rigkit.synth.io import frame_name
from rigkit.synth.session import rig_for_scene

DEMO_SIZE = (1536, 1152)
"""Demo frame size (width, height), px, that of the bundled example: small, so the checks
and processing take seconds, yet large enough that at ``DEMO_RANGE_M`` the disparity
offset the run measures stays under the 0.3 % of depth a "done" verdict allows (at
1024x768 and 250 m it was 0.72 %, and the demo's verdict said "capture again")."""
DEMO_RANGE_M = 200.0
"""The demo scene's distance, m (``rigkit rig check`` on the demo's rig.yaml: 2-sigma
depth error 0.6 % there)."""
DEMO_SEED = 7
DEMO_BURST = 3
"""Frames per position: enough for the screens' shimmer check to measure two pairs."""
LASER_NOISE_M = 0.05
SHOT_PIECES = 4
DEMO_AZIMUTH_DEG = 247.0
"""Where the demo's camera looks, degrees clockwise from true north, and how far up."""
DEMO_PITCH_DEG = 0.5
DEMO_TRIPOD = (46.5547, 7.9786, 1620.0)
"""Where the demo's tripod stands: latitude, longitude (degrees, WGS 84), height (m)."""
EDGE_FRACTION = 0.03
"""A target this close to the edge of the right or back view (of its width) gets no
depth: the matcher's windows need room."""


@dataclass(frozen=True)
class Demo:
    """The demo's folders: ``scene`` (rendered frames and ground truth), ``card`` (the
    watched folder frames arrive in), ``capture`` (sessions), ``rig`` (its profile).
    ``size``: the frames' (width, height), px; ``burst``: frames per position."""

    root: Path
    seed: int = DEMO_SEED
    shot_s: float = 0.8
    """Seconds between the simulated camera's pieces of a file and the laser's shots."""
    size: tuple[int, int] = DEMO_SIZE
    burst: int = DEMO_BURST

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

    def prepare(self, say: Callable[[str], None] = lambda text: None) -> None:
        """Render the scene where it is not yet (saying so through ``say``), and create
        the demo session with the tripod's position where it does not exist."""
        if not self.rig.is_file():
            say(f"rendering the demo scene ({self.size[0]}x{self.size[1]} px, a burst of "
                f"{self.burst} per position); it takes a little while ...")
            render_demo(self)
        if not is_session(self.session):
            create_session(self.session, self.rig)
            lat, lon, height = DEMO_TRIPOD
            set_tripod_position(self.session, TripodPosition(lat, lon, height, "manual",
                                                             utc_now()))

    def shoot(self, position: str, number: int) -> Path:
        """Write frame ``number`` (0-based) of ``position``'s burst into the card as
        ``DSCN<n>.PNG`` in pieces, ``shot_s / 8`` seconds apart (blocking). Returns the
        file."""
        data = (self.scene / frame_name(position, number)).read_bytes()
        index = ("left", "right", "back").index(position)
        target = self.card / f"DSCN{100 + 10 * index + number:04d}.PNG"
        step = math.ceil(len(data) / SHOT_PIECES)
        with target.open("wb") as handle:
            for start in range(0, len(data), step):
                handle.write(data[start:start + step])
                handle.flush()
                time.sleep(self.shot_s / 8)
        return target

    def laser_url(self, pixel: tuple[float, float]) -> str:
        """A simulated TruPulse aimed at ``pixel`` of the left view: it fires every
        ``shot_s`` seconds and reports the true range there, with the azimuth and
        inclination of that line of sight."""
        azimuth, inclination = sight_deg(self.scene, pixel)
        return (f"sim://trupulse?distance={true_range_m(self.scene, pixel):.3f}"
                f"&noise={LASER_NOISE_M}&interval={self.shot_s:g}"
                f"&inclination={inclination:.2f}&azimuth={azimuth:.2f}&seed={self.seed}")

    def no_depth(self, pixel: tuple[float, float]) -> str:
        """Why the depth map will have no depth at ``pixel`` of the left view ("" where
        it will): nothing there (sky), or a point the right or back view does not see."""
        return no_depth(self.scene, pixel)


def _left_point(scene: Path, pixel: tuple[float, float]) -> np.ndarray | None:
    """The scene point seen at ``pixel`` of the left view, (3,) m in the left camera's
    frame, None where nothing is there (the median depth of a 7 px window)."""
    truth = load_scene(scene)
    depth = truth.depth("left")
    u, v = round(pixel[0]), round(pixel[1])
    window = depth[max(v - 3, 0):v + 4, max(u - 3, 0):u + 4]
    if not np.isfinite(window).any():
        return None
    left = truth.cameras["left"]
    ray = left.rays(np.array([float(pixel[0])]), np.array([float(pixel[1])]))[0]
    return np.asarray(ray * float(np.nanmedian(window)), dtype=np.float64)


def true_range_m(scene: Path, pixel: tuple[float, float]) -> float:
    """Distance from the left camera's centre to the scene point seen at ``pixel``, m
    (the farthest depth of the scene where nothing is there)."""
    point = _left_point(scene, pixel)
    if point is None:
        truth = load_scene(scene)
        z = float(np.nanmax(truth.depth("left")))
        ray = truth.cameras["left"].rays(np.array([float(pixel[0])]),
                                         np.array([float(pixel[1])]))[0]
        point = ray * z
    return float(np.linalg.norm(point - load_scene(scene).cameras["left"].C))


def sight_deg(scene: Path, pixel: tuple[float, float]) -> tuple[float, float]:
    """(azimuth clockwise from true north, inclination up), degrees, of the line of
    sight through ``pixel`` of the left view, for the demo's camera aimed at
    ``DEMO_AZIMUTH_DEG`` and ``DEMO_PITCH_DEG`` (its frame: x right, y down, z ahead)."""
    left = load_scene(scene).cameras["left"]
    x, y, z = left.rays(np.array([float(pixel[0])]), np.array([float(pixel[1])]))[0]
    a, p = math.radians(DEMO_AZIMUTH_DEG), math.radians(DEMO_PITCH_DEG)
    ahead = np.array([math.sin(a) * math.cos(p), math.cos(a) * math.cos(p), math.sin(p)])
    right = np.array([math.cos(a), -math.sin(a), 0.0])
    up = np.cross(right, ahead)
    east, north, height = x * right - y * up + z * ahead  # ENU
    azimuth = math.degrees(math.atan2(east, north)) % 360.0
    return azimuth, math.degrees(math.atan2(height, math.hypot(east, north)))


def no_depth(scene: Path, pixel: tuple[float, float]) -> str:
    """:meth:`Demo.no_depth`."""
    point = _left_point(scene, pixel)
    if point is None:
        return "on the sky"
    truth = load_scene(scene)
    for view in ("right", "back"):
        camera = truth.cameras[view]
        (u, v), _ = camera.project(point)
        margin = EDGE_FRACTION * camera.width
        if not (margin <= u <= camera.width - margin and margin <= v <= camera.height - margin):
            return f"outside what the {view} view sees"
    return ""


def demo_params(size: tuple[int, int], burst: int = DEMO_BURST) -> SynthParams:
    """The demo scene's settings at ``size`` (width, height) px: the synthetic defaults
    at ``DEMO_RANGE_M``, with principal points off centre by as much of the frame as
    the defaults' 30 px are of 4608 px (a smaller sensor of the same make, not a 30 px
    offset on a 1536 px frame, whose bend of the back view alone would leave the
    disparity offset 0.37 % of depth), and ``burst`` frames per position under
    moderate heat shimmer (:func:`rigkit.rig.bursts.default_shimmer`: 0.1 px over 15 px
    at 1536 px)."""
    defaults = SynthParams()
    shimmer, corr = default_shimmer(focal_from_fov(size[0], defaults.hfov_deg))
    return SynthParams(width=size[0], height=size[1], distance_m=DEMO_RANGE_M,
                       max_pp_offset_px=defaults.max_pp_offset_px * size[0] / defaults.width,
                       burst=burst, shimmer_px=shimmer if burst > 1 else 0.0,
                       shimmer_corr_px=corr)


def render_demo(demo: Demo) -> None:
    """Render ``demo``'s scene and write its rig profile; the card and capture folders
    are made."""
    scene = generate_scene(demo_params(demo.size, demo.burst), demo.seed)
    write_scene(scene, demo.scene)
    demo.card.mkdir(parents=True, exist_ok=True)
    demo.capture.mkdir(parents=True, exist_ok=True)
    write_text(demo.rig, dump_yaml(rig_for_scene(scene)))


def prepare_demo(root: Path, seed: int = DEMO_SEED, size: tuple[int, int] = DEMO_SIZE,
                 shot_s: float = 0.8, burst: int = DEMO_BURST) -> Demo:
    """Render the demo scene under ``root`` and write its rig profile; returns the folders."""
    demo = Demo(root, seed, shot_s, size, burst)
    render_demo(demo)
    return demo
