"""Exact ray casting of a :class:`~rigkit.synth.scene.Scene`.

Every pixel centre casts one ray (through the lens distortion, when the scene has
one); the nearest hit among the terrain (solved by fixed-point iteration to
micrometres, cut away above the skyline), the boxes (slab test; facades and the parts
of the movers there when this view is taken included) and the spheres (closed form)
gives the depth and the surface point whose texture (a photograph, or a facade's
walls and windows) is looked up. Cloud shadows, where the scene has them, dim the
surface by their factor at that point for this view. Rays that hit nothing see a
smooth sky; haze blends every hit towards the sky's brightness with distance.

:func:`expose` turns that radiance into one 8-bit frame: heat shimmer (a random
displacement field, new in every frame, :mod:`rigkit.synth.shimmer`), a small Gaussian
point-spread function, vignetting, the frame's gain and offset, shot and read noise.
"""

from __future__ import annotations

from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from functools import cache

import cv2
import numpy as np

from rigkit.geometry import Camera, euler_to_matrix, undistort
from rigkit.synth.facades import FacadeLook, facade_albedo
from rigkit.synth.ground import Ground
from rigkit.synth.movers import Paint, painted
from rigkit.synth.scene import Scene
from rigkit.synth.shadows import shadow_factor
from rigkit.synth.shapes import FACE_SHIFT, Box, Sphere, Terrain, TextureMap
from rigkit.synth.shimmer import displacement_field

TERRAIN = 0
CHUNK_ROWS = 192
COARSE = 8  # coarse-grid step (px) that seeds the terrain iteration
PSF_SIGMA_PX = 0.5
GROUND_START = 0.3  # a ground's coarse march starts this fraction of its near range out


@cache
def _photo(name: str) -> np.ndarray:
    from skimage import color, data

    img = getattr(data, name)()
    if img.ndim == 3:
        img = color.rgb2gray(img[..., :3])
    img = img.astype(np.float32)
    img = (img - img.min()) / max(float(img.max() - img.min()), 1e-6)
    return img


@cache
def _texture(tex: TextureMap) -> np.ndarray:
    """Photograph mixed with fine noise, float32 in [0, 1]: detail at the texel scale."""
    photo = _photo(tex.photo)
    rng = np.random.default_rng(tex.noise_seed)
    noise = cv2.GaussianBlur(rng.random(photo.shape, dtype=np.float32), (0, 0), 0.7)
    noise = (noise - noise.mean()) / (noise.std() + 1e-6)
    return np.clip(0.15 + 0.6 * photo + 0.12 * noise, 0.02, 1.0).astype(np.float32)


def _mirror(x: np.ndarray, n: int) -> np.ndarray:
    period = 2.0 * (n - 1)
    x = np.mod(x, period)
    return np.where(x > n - 1, period - x, x)


def sample_texture(tex: TextureMap, s: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Albedo at surface coordinates ``(s, t)`` (metres in the surface's own frame)."""
    img = _texture(tex)
    a = np.radians(tex.angle_deg)
    su = (np.cos(a) * s - np.sin(a) * t) / tex.texel_m + tex.offset[0]
    sv = (np.sin(a) * s + np.cos(a) * t) / tex.texel_m + tex.offset[1]
    # cv2.remap wants 2D maps under 32767 on a side: lay the samples out in rows of 1024.
    n = su.size
    pad = (-n) % 1024
    mx = np.pad(_mirror(su.ravel(), img.shape[1]), (0, pad)).astype(np.float32).reshape(-1, 1024)
    my = np.pad(_mirror(sv.ravel(), img.shape[0]), (0, pad)).astype(np.float32).reshape(-1, 1024)
    out = cv2.remap(img, mx, my, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REFLECT)
    return out.ravel()[:n].reshape(s.shape)


def _terrain_t(scene: Scene, o: np.ndarray, d: np.ndarray, t: np.ndarray, iters: int) -> np.ndarray:
    """Solve o_z + t d_z = g(o_x + t d_x, o_y + t d_y) by fixed-point iteration."""
    assert isinstance(scene.terrain, Terrain)
    g = scene.terrain.z
    for _ in range(iters):
        t = (g(o[0] + t * d[..., 0], o[1] + t * d[..., 1]) - o[2]) / d[..., 2]
    return t


def terrain_seed(scene: Scene, cam: Camera) -> np.ndarray:
    """Terrain ray parameter on a coarse pixel grid, upsampled to full size (float64);
    for a :class:`Ground`, a start before each pixel's first hit (:func:`ground_seed`)."""
    hc, wc = -(-cam.height // COARSE), -(-cam.width // COARSE)
    uc = (np.arange(wc) + 0.5) * COARSE - 0.5
    vc = (np.arange(hc) + 0.5) * COARSE - 0.5
    d = cam.rays(*np.meshgrid(uc, vc))
    if isinstance(scene.terrain, Ground):
        return ground_seed(scene.terrain, cam, d)
    t0 = np.full(d.shape[:2], scene.terrain.base - cam.C[2])
    tc = _terrain_t(scene, cam.C, d, t0, iters=12)
    full = cv2.resize(tc, (wc * COARSE, hc * COARSE), interpolation=cv2.INTER_LINEAR)
    return full[: cam.height, : cam.width]


def ground_seed(ground: Ground, cam: Camera, d: np.ndarray) -> np.ndarray:
    """(H, W) float64: for every pixel of ``cam``, a ray parameter before its first hit
    with ``ground`` (:meth:`Ground.refine` finishes from there): the least exact hit
    among the coarse rays ``d`` (hc, wc, 3) around it (3 x 3), less 1 %; inf where none
    of them hits (the ground turns over metres, three coarse cells span centimetres: no
    hill peeks up between rays that all pass over it)."""
    start = np.full(d.shape[:2], GROUND_START * ground.near)
    tc = ground.hits(cam.C, d, start)
    least = cv2.erode(np.where(np.isfinite(tc), tc, 1e12), np.ones((3, 3), np.uint8))
    least = np.where(least < 1e12, 0.99 * least, np.inf)
    full = np.repeat(np.repeat(least, COARSE, axis=0), COARSE, axis=1)
    return full[: cam.height, : cam.width]


def _ground_layer(ground: Ground, o: np.ndarray, d: np.ndarray, seed: np.ndarray
                  ) -> tuple[np.ndarray, ...]:
    """The ground's first hits ``t`` of rays ``d`` (..., 3) from ``o`` searched from
    ``seed``, its normals, the fine texture's and the fields' coordinates there."""
    t = ground.refine(o, d, seed)
    X = o + np.where(np.isfinite(t), t, 0.0)[..., None] * d
    st, fields = ground.surface_coords(X)
    return t, ground.normal(X), st, fields


def _fields(scene: Scene, xz: np.ndarray) -> np.ndarray:
    """(N,) float32 brightness factor of the ground's fields and patches at ground
    coordinates ``xz`` (N, 2), m: a second texture at a coarse scale, foreshortened."""
    ground = scene.terrain
    assert isinstance(ground, Ground)
    tex = scene.textures[ground.patches]
    assert isinstance(tex, TextureMap)
    return (0.55 + 0.9 * sample_texture(tex, xz[:, 0], xz[:, 1])).astype(np.float32)


def box_hits(box: Box, o: np.ndarray, d: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Slab test. Returns t (inf on miss), world normal (.., 3) and surface coords (.., 2)."""
    Rb = euler_to_matrix(*box.euler_deg).T  # world -> box axes
    half = np.array(box.half)
    ol = Rb @ (o - np.array(box.center))
    dl = d @ Rb.T
    with np.errstate(divide="ignore", invalid="ignore"):
        t1 = (-half - ol) / dl
        t2 = (half - ol) / dl
    tn = np.nanmax(np.minimum(t1, t2), axis=-1)
    tf = np.nanmin(np.maximum(t1, t2), axis=-1)
    hit = (tn <= tf) & (tn > 0)
    t = np.where(hit, tn, np.inf)
    axis = np.argmax(np.minimum(t1, t2), axis=-1)
    p = ol + np.where(hit, tn, 0)[..., None] * dl
    n_local = np.zeros_like(p)
    sign = np.sign(np.take_along_axis(p, axis[..., None], -1))[..., 0]
    np.put_along_axis(n_local, axis[..., None], sign[..., None], -1)
    # Surface coordinates: the two box axes other than the face normal, offset per face.
    other1 = np.take_along_axis(p, ((axis + 1) % 3)[..., None], -1)[..., 0]
    other2 = np.take_along_axis(p, ((axis + 2) % 3)[..., None], -1)[..., 0]
    face = axis * 2 + (sign > 0)
    st = np.stack([other1 + FACE_SHIFT[0] * face, other2 + FACE_SHIFT[1] * face], axis=-1)
    return t, n_local @ Rb, st


def sphere_hits(sph: Sphere, o: np.ndarray, d: np.ndarray) -> tuple[np.ndarray, ...]:
    c = np.array(sph.center)
    oc = o - c
    a = np.einsum("...i,...i->...", d, d)
    b = 2 * (d @ oc)
    cc = float(oc @ oc) - sph.radius**2
    disc = b * b - 4 * a * cc
    with np.errstate(invalid="ignore"):
        tn = (-b - np.sqrt(disc)) / (2 * a)
    hit = (disc >= 0) & (tn > 0)
    t = np.where(hit, tn, np.inf)
    n = (o + np.where(hit, tn, 0)[..., None] * d - c) / sph.radius
    st = np.stack(
        [
            sph.radius * np.arctan2(n[..., 0], -n[..., 2]),
            sph.radius * np.arcsin(np.clip(n[..., 1], -1, 1)),
        ],
        axis=-1,
    )
    return t, n, st


def object_rect(
    cam: Camera, corners: np.ndarray, bend_px: float
) -> tuple[int, int, int, int] | None:
    """Pixel rectangle (u0, u1, v0, v1) that contains the projection of ``corners``,
    widened by ``bend_px``, the most the lens distortion bends a straight edge."""
    uv, z = cam.project(corners)
    if np.any(z <= 0):
        return 0, cam.width, 0, cam.height
    margin = 2 + bend_px
    u0, v0 = np.floor(uv.min(axis=0) - margin).astype(int)
    u1, v1 = np.ceil(uv.max(axis=0) + margin + 1).astype(int)
    u0, v0 = max(u0, 0), max(v0, 0)
    u1, v1 = min(u1, cam.width), min(v1, cam.height)
    if u0 >= u1 or v0 >= v1:
        return None
    return int(u0), int(u1), int(v0), int(v1)


def max_distortion_px(cam: Camera) -> float:
    """Largest displacement (px) the lens distortion gives a pixel on the image border."""
    u = np.r_[np.linspace(0, cam.width - 1, 33), np.zeros(33), np.full(33, cam.width - 1)]
    v = np.r_[np.zeros(33), np.linspace(0, cam.height - 1, 33), np.linspace(0, cam.height - 1, 33)]
    x, y = undistort((u - cam.K[0, 2]) / cam.f, (v - cam.K[1, 2]) / cam.f, cam.distortion)
    return float(np.max(np.hypot(x * cam.f + cam.K[0, 2] - u, y * cam.f + cam.K[1, 2] - v)))


def box_corners(box: Box) -> np.ndarray:
    signs = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)])
    Rb = euler_to_matrix(*box.euler_deg)  # box axes -> world
    return np.array(box.center) + (signs * np.array(box.half)) @ Rb.T


def sphere_corners(s: Sphere) -> np.ndarray:
    signs = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)])
    return np.array(s.center) + signs * s.radius


FLAT_WINDOW_PX = 9  # full-resolution px, the stereo window at the pipeline's half scale
FLAT_MAX_STEP = 0.25 / 255  # a quarter grey level: far below any sensor's noise


@dataclass(frozen=True)
class Layers:
    """One rendered view. radiance: (H, W) float32 in [0, 1] before the PSF and noise;
    depth: (H, W) float32, metres, z in the camera's frame, NaN where no surface;
    surface: (H, W) int16, the texture index of the surface seen (0 the terrain, the
    shapes' ``texture`` otherwise), -1 where no surface."""

    radiance: np.ndarray
    depth: np.ndarray
    surface: np.ndarray

    def flat(self, window: int = FLAT_WINDOW_PX, max_step: float = FLAT_MAX_STEP) -> np.ndarray:
        """(H, W) bool: pixels with a surface whose radiance does not change along the
        rows within the ``window`` around them (RMS step between neighbouring columns
        below ``max_step``, radiance units): a plain wall, a window pane, the inside of
        a horizontal edge, an empty backdrop. Nothing there can be matched along the
        epipolar lines, by any method; a depth given there comes from its neighbours."""
        step = np.zeros_like(self.radiance)
        step[:, 1:] = np.diff(self.radiance, axis=1) ** 2
        energy = cv2.boxFilter(step, -1, (window, window))
        return (energy < max_step**2) & np.isfinite(self.depth)


def view_objects(scene: Scene, name: str) -> tuple[Box | Sphere, ...]:
    """Every box and sphere in front of the terrain when view ``name`` is taken: the
    static ones (facades included) and the movers there at that moment."""
    movers = tuple(b for m in scene.movers for b in m.boxes(name))
    return (*scene.boxes, *scene.spheres, *movers)


def albedo(tex: TextureMap | FacadeLook | Paint, s: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Albedo (float32, shape of ``s``) of a surface wearing ``tex`` at surface
    coordinates ``(s, t)`` (m)."""
    if isinstance(tex, FacadeLook):
        return facade_albedo(tex, s, t)
    if isinstance(tex, Paint):
        return painted(tex, sample_texture(tex.texture, s, t))
    return sample_texture(tex, s, t)


def objects_in_view(
    cam: Camera, objects: tuple[Box | Sphere, ...]
) -> list[tuple[Box | Sphere, tuple[int, int, int, int]]]:
    """The objects whose projection touches the image, with their pixel rectangles."""
    bend_px = max_distortion_px(cam)
    out = []
    for obj in objects:
        corners = box_corners(obj) if isinstance(obj, Box) else sphere_corners(obj)
        rect = object_rect(cam, corners, bend_px)
        if rect is not None:
            out.append((obj, rect))
    return out


def render_view(
    scene: Scene, name: str, progress: Callable[[float], None] | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """Render one camera of ``scene``: ``(radiance, depth)`` of :func:`render_layers`."""
    layers = render_layers(scene, name, progress)
    return layers.radiance, layers.depth


def render_layers(
    scene: Scene, name: str, progress: Callable[[float], None] | None = None
) -> Layers:
    """Render one camera of ``scene`` (``progress`` gets the fraction of rows done)."""
    cam = scene.cameras[name]
    H, W = cam.height, cam.width
    seed_t = terrain_seed(scene, cam)
    radiance = np.empty((H, W), np.float32)
    depth = np.empty((H, W), np.float32)
    surface = np.empty((H, W), np.int16)
    objects = objects_in_view(cam, view_objects(scene, name))
    light = np.array(scene.light) / np.linalg.norm(scene.light)
    void = scene.params.backdrop == "void"
    done = [0]

    def chunk(r0: int) -> None:
        r1 = min(r0 + CHUNK_ROWS, H)
        u, v = np.meshgrid(np.arange(W, dtype=np.float64), np.arange(r0, r1, dtype=np.float64))
        d = cam.rays(u, v)
        if isinstance(scene.terrain, Ground):
            t, normal, st, fields = _ground_layer(scene.terrain, cam.C, d, seed_t[r0:r1])
        else:
            t = _terrain_t(scene, cam.C, d, seed_t[r0:r1].copy(), iters=3)
            x, y = cam.C[0] + t * d[..., 0], cam.C[1] + t * d[..., 1]
            t = np.where(scene.terrain.above_skyline(x, y) | void, np.inf, t)
            gx, gy = scene.terrain.gradient(x, y)
            normal = np.stack([gx, gy, -np.ones_like(gx)], axis=-1)
            st = np.stack([x, y], axis=-1)
            fields = None
        sid = np.zeros(t.shape, np.int16)
        for obj, (u0, u1, v0, v1) in objects:
            a0, a1 = max(v0, r0) - r0, min(v1, r1) - r0
            if a0 >= a1:
                continue
            win = (slice(a0, a1), slice(u0, u1))
            hit = box_hits if isinstance(obj, Box) else sphere_hits
            to, no, sto = hit(obj, cam.C, d[win])  # type: ignore[arg-type]
            closer = to < t[win]
            t[win] = np.where(closer, to, t[win])
            normal[win] = np.where(closer[..., None], no, normal[win])
            st[win] = np.where(closer[..., None], sto, st[win])
            sid[win] = np.where(closer, obj.texture, sid[win])
        hit = np.isfinite(t)
        surf = np.zeros(t.shape, np.float32)
        for tex_id in np.unique(sid[hit]):
            m = hit & (sid == tex_id)
            surf[m] = albedo(scene.textures[tex_id], st[m][:, 0], st[m][:, 1])
        if fields is not None:  # the ground's fields and patches, in ground coordinates
            m = hit & (sid == TERRAIN)
            if m.any():
                surf[m] *= _fields(scene, fields[m])
        nn = normal / np.linalg.norm(normal, axis=-1, keepdims=True)
        facing = np.sign(-np.einsum("...i,...i->...", nn, d))[..., None]
        surf = surf * (0.3 + 0.7 * np.clip((nn * facing) @ light, 0, 1))
        if scene.shadows:
            X = cam.C + np.where(hit, t, 0)[..., None] * d
            surf = surf * shadow_factor(scene.shadows, X, name, scene.light,
                                        scene.params.distance_m)
        sky = np.zeros(t.shape, np.float32) if void else sky_radiance(d)
        lit = _haze(scene, surf, t * np.linalg.norm(d, axis=-1), sky)
        radiance[r0:r1] = np.where(hit, lit, sky)
        depth[r0:r1] = np.where(hit, t, np.nan)  # rays have unit camera-z
        surface[r0:r1] = np.where(hit, sid, -1)
        done[0] += r1 - r0
        if progress is not None:
            progress(done[0] / H)

    with ThreadPoolExecutor(max_workers=2) as pool:
        list(pool.map(chunk, range(0, H, CHUNK_ROWS)))
    return Layers(radiance, depth, surface)


def sky_radiance(d: np.ndarray) -> np.ndarray:
    """Brightness of a clear sky along world directions ``d`` (..., 3): smooth, brighter
    towards the horizon (+y is down) and slightly to one side, no texture."""
    elev = d[..., 1] / d[..., 2]
    return np.clip(0.80 + 1.2 * elev + 0.3 * d[..., 0] / d[..., 2], 0.55, 0.97).astype(np.float32)


def _haze(scene: Scene, radiance: np.ndarray, distance: np.ndarray, sky: np.ndarray) -> np.ndarray:
    """Koschmieder's law: surface radiance attenuated by exp(-distance / haze_m), plus
    airlight (the sky's brightness) for what was lost."""
    if scene.params.haze_m <= 0:
        return radiance
    with np.errstate(invalid="ignore"):
        trans = np.exp(-distance / scene.params.haze_m)
    return np.where(np.isfinite(trans), radiance * trans + sky * (1 - trans), sky)


def expose(scene: Scene, name: str, radiance: np.ndarray, frame: int = 0) -> np.ndarray:
    """Camera response for one frame: shimmer, PSF, vignetting, gain and offset, shot and
    read noise, 8-bit quantisation -> (H, W) uint8. ``frame`` numbers the frames of a
    burst at one position (each gets its own shimmer, offset, gain wobble and noise)."""
    p = scene.params
    rng = np.random.default_rng([scene.seed, sorted(scene.cameras).index(name), frame])
    img = radiance
    if p.shimmer_px > 0:
        dx, dy = displacement_field(img.shape, p.shimmer_px, p.shimmer_spectrum,
                                    p.shimmer_corr_px, p.shimmer_outer_px, rng)
        v, u = np.mgrid[0 : img.shape[0], 0 : img.shape[1]].astype(np.float32)
        img = cv2.remap(img, u + dx, v + dy, cv2.INTER_CUBIC, borderMode=cv2.BORDER_REFLECT)
    gain = scene.gains.get(name, 1.0) * (1.0 + 0.01 * (frame > 0) * rng.standard_normal())
    img = cv2.GaussianBlur(img, (0, 0), PSF_SIGMA_PX) * np.float32(230.0 * gain)
    if p.vignetting > 0:
        img = img * _vignette(img.shape, p.vignetting)
    img = img + np.float32(rng.uniform(-p.offset_jitter_dn, p.offset_jitter_dn))
    sigma = np.sqrt(p.noise_dn**2 + 0.05 * np.maximum(img, 0))
    img = img + sigma * rng.standard_normal(img.shape, dtype=np.float32)
    return np.clip(np.rint(img), 0, 255).astype(np.uint8)


def _vignette(shape: tuple[int, int], loss: float) -> np.ndarray:
    """(H, W) float32 brightness factor 1 - loss * (r / r_corner)^2."""
    h, w = shape
    y, x = np.ogrid[0:h, 0:w]
    cx, cy = (w - 1) / 2, (h - 1) / 2
    r2 = ((x - cx) ** 2 + (y - cy) ** 2) / (cx**2 + cy**2)
    return (1.0 - loss * r2).astype(np.float32)
