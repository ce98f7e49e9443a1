"""Random three-view scenes at long range, following the paper's synthetic protocol (sec. 5.2).

A scene is analytic geometry in the left camera's frame (metres):

* a terrain-like surface ``z = g(x, y)`` facing the cameras (a hillside or facade
  300 m away): a tilted plane plus sinusoids and Gaussian bumps;
* boxes (buildings, rocks) and spheres standing in front of it, with sharp depth
  edges that occlude the terrain differently in each view.

Each surface carries a texture made from a real photograph (``skimage.data``) mixed
with fine noise, mapped in the surface's own metric coordinates so that all three
views see the same surface pattern.

What a real capture adds (all off by default, the paper's protocol; on together with
:func:`field_params`): a skyline with no surface above it and a smooth sky, haze that
grows with distance, lens distortion (the same lens in the three views), and per frame
heat shimmer, gain, offset, vignetting and noise, with bursts of several frames per
position (see :mod:`rigkit.synth.render`; shimmer spectra in :mod:`rigkit.synth.shimmer`).

What changes between the captures, minutes apart, and what stereo finds hard (all off by
default; each drawn from a generator of its own, so a seed's scene stays as it was):
cars and people placed anew in each view (:mod:`rigkit.synth.movers`), cloud shadows
drifting over the surface (:mod:`rigkit.synth.shadows`), and building facades with
periodic windows or plain walls (:mod:`rigkit.synth.facades`). The left pixels where
the views disagree are ground truth of their own (:mod:`rigkit.synth.changes`).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field, replace

import numpy as np

from rigkit.errors import InputError
from rigkit.geometry import (
    NO_DISTORTION,
    Camera,
    Distortion,
    euler_to_matrix,
    focal_from_fov,
    intrinsics,
)
from rigkit.synth.facades import FacadeLook, make_facades
from rigkit.synth.ground import Ground, make_ground
from rigkit.synth.movers import Mover, Paint, make_movers
from rigkit.synth.shadows import CloudShadow, make_shadows
from rigkit.synth.shapes import Box, Sphere, Terrain, TextureMap, random_texture
from rigkit.synth.shimmer import SPECTRA

BACKDROPS = ("terrain", "void", "ground")


MAX_SIDE_PX = 16384
"""The widest and tallest image synth renders (a 16 MP frame is 4608 px wide)."""
MAX_SEED = 2**32 - 1
"""The largest seed a scene is drawn from."""

@dataclass(frozen=True)
class SynthParams:
    """Everything ``rigkit synth`` can set. Angles in degrees, lengths in metres."""

    width: int = 4608
    height: int = 3456
    hfov_deg: float = 6.0
    distance_m: float = 300.0  # depth of the scene centre along the left optical axis
    baseline_lr_m: float = 2.0  # right camera at (C_lr, 0, 0)
    baseline_lb_m: float = 2.0  # back camera C_lb behind the left one
    back_side_m: float = 0.0  # back camera offset to the right (+x)
    back_up_m: float = 0.3  # back camera raised by this much (-y in camera axes)
    max_tilt_deg: float = 1.0  # |x|, |y| Euler angles of right and back cameras
    max_roll_deg: float = 5.0  # |z| Euler angle of right and back cameras
    max_pp_offset_px: float = 30.0  # principal point offset from the image centre, per axis
    one_camera: bool = False  # one camera moved between the positions: one principal point
    relief: float = 0.03  # terrain depth variation, as a fraction of distance
    n_boxes: int = 7
    n_spheres: int = 3
    noise_dn: float = 1.5  # sensor read noise, 8-bit digital numbers (sigma)
    gain_jitter: float = 0.04  # per-camera exposure/gain difference (fraction)
    # What a field capture adds (0 = off):
    sky: float = 0.0  # fraction of the left image's height above the skyline (no surface)
    haze_m: float = 0.0  # extinction length: contrast falls as exp(-range / haze_m)
    offset_jitter_dn: float = 0.0  # per-frame black-level offset, uniform within +-, DN
    vignetting: float = 0.0  # brightness lost at the image corner (fraction, r^2 falloff)
    shimmer_px: float = 0.0  # heat shimmer: RMS image displacement per axis, px
    shimmer_corr_px: float = 40.0  # its correlation length (Gaussian sigma), px
    distortion: Distortion = NO_DISTORTION  # OpenCV k1, k2, p1, p2, k3 (normalised coords)
    burst: int = 1  # frames per camera position
    shimmer_spectrum: str = "gaussian"  # gaussian | fine | vonkarman (rigkit.synth.shimmer)
    shimmer_outer_px: float = 1500.0  # vonkarman: the outer scale L0, px
    # A world that moves between the captures, and hard facades (0 = off):
    n_movers: int = 0  # cars and people, placed anew in each view (rigkit.synth.movers)
    n_shadows: int = 0  # cloud shadows drifting between captures (rigkit.synth.shadows)
    shadow_drift_m: float = 6.0  # how far a cloud shadow moves between two captures, m
    n_facades: int = 0  # building facades: windowed and plain walls (rigkit.synth.facades)
    # "terrain": the objects stand on textured ground under a sky; "void": no ground,
    # an exactly black background (as the paper's own elephant scene has); "ground":
    # the cameras look down on ground receding up the view (rigkit.synth.ground)
    backdrop: str = "terrain"
    depth_ratio: float = 1.6  # "ground": depth at the top of the ground over the bottom

    def validate(self) -> None:
        """InputError naming the first parameter out of its range."""
        # Every number bounded on both sides: a value the arithmetic of rendering cannot
        # hold (noise 1e300 DN, a scene 1e300 m away) is a mistake to name, never a
        # traceback or a scene whose truth is all NaN.
        checks = {
            "width": 64 <= self.width <= MAX_SIDE_PX,
            "height": 48 <= self.height <= MAX_SIDE_PX,
            "hfov_deg": 0.1 < self.hfov_deg < 60,
            "distance_m": 10 <= self.distance_m <= 100_000,
            "baseline_lr_m": 1e-4 <= self.baseline_lr_m <= 100,
            "baseline_lb_m": 1e-4 <= self.baseline_lb_m <= 100,
            "back_side_m": abs(self.back_side_m) <= 100,
            "back_up_m": abs(self.back_up_m) <= 100,
            "max_tilt_deg": 0 <= self.max_tilt_deg <= 10,
            "max_roll_deg": 0 <= self.max_roll_deg <= 45,
            "max_pp_offset_px": 0 <= self.max_pp_offset_px <= max(self.width, self.height),
            "relief": 0 <= self.relief < 0.5,
            "noise_dn": 0 <= self.noise_dn <= 64,
            "gain_jitter": 0 <= self.gain_jitter < 0.5,
            "n_boxes": 0 <= self.n_boxes <= 500,
            "n_spheres": 0 <= self.n_spheres <= 500,
            "sky": 0 <= self.sky < 0.8,
            "haze_m": 0 <= self.haze_m <= 1e7,
            "offset_jitter_dn": 0 <= self.offset_jitter_dn <= 64,
            "vignetting": 0 <= self.vignetting < 1,
            "shimmer_px": 0 <= self.shimmer_px < 20,
            "shimmer_corr_px": 0 < self.shimmer_corr_px <= 1e6,
            "distortion": len(self.distortion) == 5 and all(np.isfinite(self.distortion)),
            "burst": 1 <= self.burst <= 50,
            "shimmer_spectrum": self.shimmer_spectrum in SPECTRA,
            "shimmer_outer_px": 0 < self.shimmer_outer_px <= 1e7,
            "n_movers": 0 <= self.n_movers <= 500,
            "n_shadows": 0 <= self.n_shadows <= 50,
            "shadow_drift_m": 0 <= self.shadow_drift_m <= 1000,
            "n_facades": 0 <= self.n_facades <= 50,
            "backdrop": self.backdrop in BACKDROPS,
            "depth_ratio": 1.05 <= self.depth_ratio <= 4.0,
        }
        for name, ok in checks.items():
            if not ok:
                raise InputError(f"synth parameter {name}={getattr(self, name)!r} is out of range")
        if self.backdrop == "ground" and (self.n_movers or self.n_facades):
            raise InputError("synth: movers and facades stand on a terrain facing the "
                             "cameras; the ground backdrop has none (set them to 0)")

    @property
    def focal_px(self) -> float:
        return focal_from_fov(self.width, self.hfov_deg)


def field_params(base: SynthParams | None = None) -> SynthParams:
    """``base`` (default: the paper's protocol) with what a realistic field capture has:
    a skyline with sky above ~25 % of the frame, haze (contrast 0.82 at 300 m),
    per-frame gain +-10 % and offset +-6 DN, 25 % vignetting at the corner, and heat
    shimmer of 0.3 px RMS per axis correlated over 1 % of the image width - moderate
    turbulence over 300 m at ~19 urad per pixel (docs/synthetic-scenes.md). Lens
    distortion and bursts stay as in ``base``."""
    base = base or SynthParams()
    return replace(
        base,
        sky=0.25,
        haze_m=1500.0,
        gain_jitter=0.10,
        offset_jitter_dn=6.0,
        vignetting=0.25,
        shimmer_px=0.3,
        shimmer_corr_px=0.01 * base.width,
    )


@dataclass(frozen=True)
class Scene:
    params: SynthParams
    seed: int
    cameras: dict[str, Camera]
    euler_deg: dict[str, tuple[float, float, float]]
    terrain: Terrain | Ground
    boxes: tuple[Box, ...]  # facades included: boxes whose texture is a FacadeLook
    spheres: tuple[Sphere, ...]
    textures: tuple[TextureMap | FacadeLook | Paint, ...]  # indexed by shapes' ``texture``
    light: tuple[float, float, float] = field(default=(0.35, -0.55, -0.76))
    gains: dict[str, float] = field(default_factory=dict)
    movers: tuple[Mover, ...] = ()
    shadows: tuple[CloudShadow, ...] = ()

    def description(self) -> dict[str, object]:
        """Plain data describing the geometry (for scene.yaml)."""
        return {
            "terrain": asdict(self.terrain),
            "boxes": [asdict(b) for b in self.boxes],
            "spheres": [asdict(s) for s in self.spheres],
            "textures": [asdict(t) for t in self.textures],
            "light": list(self.light),
            "movers": [asdict(m) for m in self.movers],
            "cloud_shadows": [asdict(c) for c in self.shadows],
        }

    def moving_textures(self) -> set[int]:
        """Texture indices that only movers wear: what marks a mover in a surface map."""
        return {m.texture for m in self.movers}


def _cameras(p: SynthParams, rng: np.random.Generator) -> tuple[dict[str, Camera], dict]:
    f = p.focal_px
    cams: dict[str, Camera] = {}
    eulers: dict[str, tuple[float, float, float]] = {}
    left_pp = np.zeros(2)
    centres = {
        "left": (0.0, 0.0, 0.0),
        "right": (p.baseline_lr_m, 0.0, 0.0),
        "back": (p.back_side_m, -p.back_up_m, -p.baseline_lb_m),
    }
    for name, centre in centres.items():
        if name == "left":
            e = (0.0, 0.0, 0.0)
        else:
            tx, ty = rng.uniform(-p.max_tilt_deg, p.max_tilt_deg, 2)
            e = (float(tx), float(ty), float(rng.uniform(-p.max_roll_deg, p.max_roll_deg)))
        pp = rng.uniform(-p.max_pp_offset_px, p.max_pp_offset_px, 2)  # drawn either way
        if p.one_camera and name != "left":
            pp = left_pp  # the same camera's principal point at every position
        left_pp = pp if name == "left" else left_pp
        K = intrinsics(f, (p.width - 1) / 2 + pp[0], (p.height - 1) / 2 + pp[1])
        # euler_to_matrix gives the camera's orientation (camera -> world); R is its inverse.
        R = euler_to_matrix(*e).T
        cams[name] = Camera(
            K=K, R=R, C=np.array(centre), width=p.width, height=p.height, distortion=p.distortion
        )
        eulers[name] = e
    return cams, eulers


def _skyline(
    p: SynthParams, rng: np.random.Generator, half_w: float, half_h: float
) -> tuple[float, tuple[tuple[float, float, float], ...]] | None:
    """A ridge line about ``p.sky`` of the height below the top of the left view."""
    if p.sky <= 0:
        return None
    y0 = -half_h + 2 * half_h * p.sky
    waves = []
    for _ in range(4):
        k = 2 * np.pi / (rng.uniform(0.1, 1.0) * 2 * half_w)
        amp = float(rng.uniform(0.02, 0.08) * half_h)
        waves.append((amp, float(k), float(rng.uniform(0, 2 * np.pi))))
    return float(y0), tuple(waves)


def _terrain(p: SynthParams, rng: np.random.Generator, half_w: float) -> Terrain:
    relief = p.relief * p.distance_m
    waves = []
    for _ in range(6):
        wavelength = rng.uniform(0.15, 1.0) * half_w * 2
        k = 2 * np.pi / wavelength
        theta = rng.uniform(0, 2 * np.pi)
        # keep slopes bounded: amplitude * k <= 0.25
        amp = min(rng.uniform(0.05, 0.15) * relief, 0.25 / k)
        waves.append((amp, k * np.cos(theta), k * np.sin(theta), rng.uniform(0, 2 * np.pi)))
    bumps = []
    for _ in range(4):
        s = rng.uniform(0.1, 0.3) * half_w
        b = rng.uniform(-0.35, 0.35) * relief
        b = float(np.sign(b) * min(abs(b), 0.4 * s))
        bumps.append((b, *rng.uniform(-half_w, half_w, 2), s))
    slope = tuple(rng.uniform(-0.25, 0.25, 2) * relief / half_w)
    return Terrain(
        base=p.distance_m,
        slope=(float(slope[0]), float(slope[1])),
        waves=tuple(tuple(float(v) for v in w) for w in waves),  # type: ignore[misc]
        bumps=tuple(tuple(float(v) for v in b) for b in bumps),  # type: ignore[misc]
        texture=0,
    )


def generate_scene(params: SynthParams, seed: int) -> Scene:
    """Draw a random scene and rig from ``seed`` (a whole number 0 to 2^32 - 1; the same
    seed gives the same scene)."""
    params.validate()
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) \
            or not 0 <= seed <= MAX_SEED:
        raise InputError(f"synth seed {seed!r} is out of range: a whole number from 0 to "
                         f"{MAX_SEED}")
    rng = np.random.default_rng(seed)
    cams, eulers = _cameras(params, rng)
    if params.backdrop == "ground":
        return _ground_scene(params, seed, cams, eulers, rng)
    f = params.focal_px
    half_w = params.distance_m * params.width / 2 / f
    half_h = params.distance_m * params.height / 2 / f
    terrain = _terrain(params, rng, half_w)
    if params.sky > 0:
        # Its own generator, so that a sky leaves the rest of the seed's scene as it was.
        sky_rng = np.random.default_rng([seed, 7])
        terrain = replace(terrain, skyline=_skyline(params, sky_rng, half_w, half_h))
    n_tex = 1 + params.n_boxes + params.n_spheres
    pixel_m = params.distance_m / f
    textures = tuple(random_texture(rng, pixel_m) for _ in range(n_tex))
    relief = params.relief * params.distance_m
    boxes = []
    for i in range(params.n_boxes):
        x, y = rng.uniform(-0.85, 0.85) * half_w, rng.uniform(-0.85, 0.85) * half_h
        z = float(terrain.z(np.array(x), np.array(y))) - rng.uniform(0.3, 1.2) * max(relief, 1)
        half = (
            float(rng.uniform(0.06, 0.2) * half_w),
            float(rng.uniform(0.06, 0.25) * half_h),
            float(rng.uniform(0.5, 3.0)),
        )
        e = (float(rng.uniform(-10, 10)), float(rng.uniform(-40, 40)), float(rng.uniform(-8, 8)))
        boxes.append(Box((float(x), float(y), z), half, e, texture=1 + i))
    spheres = []
    for i in range(params.n_spheres):
        x, y = rng.uniform(-0.85, 0.85) * half_w, rng.uniform(-0.85, 0.85) * half_h
        r = float(rng.uniform(0.05, 0.12) * half_w)
        z = float(terrain.z(np.array(x), np.array(y))) - r - rng.uniform(0.2, 0.8) * max(relief, 1)
        spheres.append(Sphere((float(x), float(y), z), r, texture=1 + params.n_boxes + i))
    gains = {name: float(1 + rng.uniform(-params.gain_jitter, params.gain_jitter)) for name in cams}
    scene = Scene(
        params=params,
        seed=seed,
        cameras=cams,
        euler_deg=eulers,
        terrain=terrain,
        boxes=tuple(boxes),
        spheres=tuple(spheres),
        textures=textures,
        gains=gains,
    )
    return _add_world(scene, seed, half_w, half_h)


def _ground_scene(params: SynthParams, seed: int, cams: dict[str, Camera],
                  eulers: dict[str, tuple[float, float, float]], rng: np.random.Generator
                  ) -> Scene:
    """A scene looking down on ground that recedes up the view (:mod:`rigkit.synth.ground`)."""
    ground, boxes, spheres, textures = make_ground(params, rng)
    gains = {name: float(1 + rng.uniform(-params.gain_jitter, params.gain_jitter)) for name in cams}
    half_w = params.distance_m * params.width / 2 / params.focal_px
    shadows = make_shadows(params.n_shadows, half_w, params.shadow_drift_m,
                           np.random.default_rng([seed, 17]))  # as _add_world draws them
    return Scene(params=params, seed=seed, cameras=cams, euler_deg=eulers, terrain=ground,
                 boxes=boxes, spheres=spheres, textures=textures, gains=gains,
                 shadows=shadows)


def _add_world(scene: Scene, seed: int, half_w: float, half_h: float) -> Scene:
    """``scene`` with its facades, movers and cloud shadows. Each draws from a generator
    of its own, so that they leave the rest of the seed's scene as it was."""
    p = scene.params
    assert isinstance(scene.terrain, Terrain)  # they stand on a terrain facing the cameras
    relief = p.relief * p.distance_m
    n = len(scene.textures)
    facades, looks = make_facades(p.n_facades, scene.terrain, half_w, half_h, relief, n,
                                  np.random.default_rng([seed, 11]))
    movers, coats = make_movers(p.n_movers, scene.terrain, half_w, half_h,
                                p.distance_m / p.focal_px, n + len(looks),
                                np.random.default_rng([seed, 13]))
    shadows = make_shadows(p.n_shadows, half_w, p.shadow_drift_m,
                           np.random.default_rng([seed, 17]))
    return replace(scene, boxes=scene.boxes + facades, textures=scene.textures + looks + coats,
                   movers=movers, shadows=shadows)
