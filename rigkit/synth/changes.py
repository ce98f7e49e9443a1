"""Ground truth of what differs between the three captures, as masks on the left view.

``moved_left`` (H, W) bool: a left pixel is *moved* when

* a mover is what the left camera sees there (its surface map says so), or
* the surface point ``X`` the left camera sees there (lifted with the ground-truth
  depth) is hidden in the right or the back view by a mover that is there when that
  view is taken: ``X`` projects inside that image, and the segment from that camera's
  centre to ``X`` passes through one of the mover's boxes before it meets any static
  box or sphere (slab and sphere tests, exact). The terrain is not tested as an
  occluder of a mover: movers stand clear in front of it.

``shadow_changed_left`` (H, W) bool: a left pixel whose surface point lies under a
different cloud-shadow factor in the right or the back view than in the left, by more
than ``SHADOW_CHANGE`` of the light (:mod:`rigkit.synth.shadows`): there the views
disagree about the point's brightness though not about its place.

The two are kept apart: a moved pixel has no correct match in at least one view, a
shadow-changed one has its match, only darker or brighter.
"""

from __future__ import annotations

import numpy as np

from rigkit.geometry import Camera
from rigkit.synth.render import (
    CHUNK_ROWS,
    box_corners,
    box_hits,
    max_distortion_px,
    object_rect,
    sphere_hits,
)
from rigkit.synth.scene import Scene
from rigkit.synth.shadows import shadow_factor
from rigkit.synth.shapes import Box

SHADOW_CHANGE = 0.02  # shadow factor difference (fraction of the light) that counts
OTHER_VIEWS = ("right", "back")


def _lift(cam: Camera, depth: np.ndarray, r0: int) -> np.ndarray:
    """(h, W, 3) float64 world points (m) of rows ``r0 ...`` of a camera whose depth map
    (h, W) float32 (z in that camera, m; NaN = none) is ``depth``."""
    v, u = np.mgrid[r0 : r0 + depth.shape[0], 0 : depth.shape[1]].astype(np.float64)
    return cam.C + cam.rays(u, v) * depth[..., None].astype(np.float64)


def _first_static_hit(scene: Scene, cam: Camera, d: np.ndarray) -> np.ndarray:
    """(N,) float64: the ray parameter of the nearest static box or sphere along rays
    ``cam.C + t d`` (``d`` (N, 3)), inf where none."""
    t = np.full(len(d), np.inf)
    for obj in (*scene.boxes, *scene.spheres):
        hit = box_hits if isinstance(obj, Box) else sphere_hits
        t = np.minimum(t, hit(obj, cam.C, d)[0])  # type: ignore[arg-type]
    return t


def _hidden_by_movers(scene: Scene, view: str, X: np.ndarray, ask: np.ndarray) -> np.ndarray:
    """(h, W) bool: which world points ``X`` (h, W, 3) among ``ask`` (h, W) bool a mover
    hides from camera ``view``."""
    cam = scene.cameras[view]
    out = np.zeros(ask.shape, bool)
    movers = [b for m in scene.movers for b in m.boxes(view)]
    if not movers:
        return out
    with np.errstate(invalid="ignore"):
        uv, z = cam.project(X)
        inside = ask & (z > 0) & (uv[..., 0] > -0.5) & (uv[..., 0] < cam.width - 0.5)
        inside &= (uv[..., 1] > -0.5) & (uv[..., 1] < cam.height - 0.5)
    bend_px = max_distortion_px(cam)
    for box in movers:
        rect = object_rect(cam, box_corners(box), bend_px)
        if rect is None:
            continue
        u0, u1, v0, v1 = rect
        cand = inside & (uv[..., 0] >= u0) & (uv[..., 0] < u1)
        cand &= (uv[..., 1] >= v0) & (uv[..., 1] < v1)
        if not cand.any():
            continue
        d = X[cand] - cam.C  # X at t = 1
        t_mover = box_hits(box, cam.C, d)[0]
        hidden = (t_mover < 1) & (t_mover < _first_static_hit(scene, cam, d))
        out[cand] |= hidden
    return out


def moved_left(scene: Scene, surface: np.ndarray, depth: np.ndarray) -> np.ndarray:
    """(H, W) bool: the left pixels a mover covers in any view (module docstring).

    surface: (H, W) int16, the left view's surface map (texture index seen, -1 none);
    depth: (H, W) float32, the left view's ground-truth depth (m, NaN = none)."""
    cam = scene.cameras["left"]
    moved = np.isin(surface, sorted(scene.moving_textures()))
    for r0 in range(0, cam.height, CHUNK_ROWS):
        rows = slice(r0, min(r0 + CHUNK_ROWS, cam.height))
        X = _lift(cam, depth[rows], r0)
        ask = np.isfinite(depth[rows]) & ~moved[rows]
        for view in OTHER_VIEWS:
            moved[rows] |= _hidden_by_movers(scene, view, X, ask)
    return moved


def shadow_changed_left(scene: Scene, depth: np.ndarray) -> np.ndarray:
    """(H, W) bool: left pixels whose surface point's cloud-shadow factor differs
    between the left and the right or back view by more than ``SHADOW_CHANGE``.
    depth: (H, W) float32, the left view's ground-truth depth (m, NaN = none)."""
    cam = scene.cameras["left"]
    changed = np.zeros(depth.shape, bool)
    if not scene.shadows:
        return changed
    args = (scene.light, scene.params.distance_m)
    for r0 in range(0, cam.height, CHUNK_ROWS):
        rows = slice(r0, min(r0 + CHUNK_ROWS, cam.height))
        X = _lift(cam, np.nan_to_num(depth[rows]), r0)
        left = shadow_factor(scene.shadows, X, "left", *args)
        for view in OTHER_VIEWS:
            other = shadow_factor(scene.shadows, X, view, *args)
            changed[rows] |= np.abs(other - left) > SHADOW_CHANGE
        changed[rows] &= np.isfinite(depth[rows])
    return changed
