"""Ground seen at a grazing angle: a valley floor, a road, a hillside receding up the view.

The terrain of :mod:`rigkit.synth.shapes` is a surface ``z = g(x, y)`` facing the
cameras, so that one view spans a few percent of depth. Long-range views from a hill
look *down* on the ground instead: the bottom of the frame sees ground 200 m away, the
top 400 m or more, then a rim with sky above. This module builds such a world
independently of the depth pipeline's assumptions: a height field in a level frame of
its own, a camera pitched down onto it, texture fixed to the ground, and exact first
hits (nearer hills hide the ground behind them).

Frames (metres): the *ground frame* ``G`` has X right, Y down (gravity) and Z forward,
level, with its origin at the left camera; the left camera is ``G`` pitched down by
``pitch_deg`` and rolled by ``roll_deg`` (``X_cam = R_cg @ X_G``, :meth:`Ground.to_camera`).
The surface is ``Y = height - e(X, Z)``: ``e`` is the elevation above the datum
``height`` metres below the camera, a gentle slope, waves and bumps (hills and hollows)
and a hillside rising towards the rim. Beyond the rim ``Z > rim(X)`` there is no ground
(the view ends in sky).

Ray casting: along a ray ``o + t d`` the signed height above ground
``F(t) = Y(t) - height + e(X(t), Z(t))`` is negative until the first hit. ``|dF/dt|`` is
bounded by ``|d_Y| + G |d_XZ|`` (``G``: a bound on ``|grad e|``, :meth:`Ground.slope_bound`),
so a step of ``-F / bound`` can never pass a root (Lipschitz ray marching, as in
Hart's sphere tracing, 1996); near the surface Newton's method finishes to
micrometres. The march runs on a coarse grid of pixels first; each full-resolution ray
starts from the least hit among its coarse neighbours, less a margin, which lies
before its own first hit wherever the ground does not turn in less than a coarse cell.

Texture: surface coordinates ``s = X``, ``t = height * ln(Z / near) + e`` (m) keep a
texel about as tall as it is wide in the image at every range (a pixel covers
``Z / f`` across and ``Z^2 / (f height)`` along the ground), so that one ray per pixel
samples it without aliasing; large fields and patches of another texture, laid in
true ground coordinates, are foreshortened as a real valley's are.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import TYPE_CHECKING

import numpy as np

from rigkit.geometry import rot_x, rot_y, rot_z
from rigkit.synth.shapes import Box, Sphere, TextureMap, random_texture

if TYPE_CHECKING:
    from rigkit.synth.scene import SynthParams

MARCH_TOL_M = 0.2
"""The march stops this close above the ground (m); Newton finishes from there."""
MARCH_STEPS = 400
"""Most Lipschitz steps a ray takes before it is taken to pass over everything."""
NEWTON_STEPS = 30
RIM_NONE = 3.0
"""Without sky, the rim lies this many times the far range out: beyond the view."""
NEWTON_TOL_M = 1e-6


@dataclass(frozen=True)
class Ground:
    """A height field seen from above at a grazing angle (see the module docstring).

    ``height``: the left camera above the datum, m; ``pitch_deg``, ``roll_deg``: the
    left camera's pitch down and roll against the level ground frame; ``slope``:
    (dE/dX, dE/dZ) of the datum; ``waves``: (A, kx, kz, phase), m and rad/m;
    ``bumps``: (B, X0, Z0, sigma), m; ``hill``: (rise, Z0, width) a hillside rising by
    ``rise`` m as a smoothstep from ``Z0`` over ``width`` m (rise 0: none); ``rim``:
    (Z0, ((A, k, phase), ...)) the ground ends at ``Z = Z0 + sum A sin(k X + phase)``;
    ``near``: the nearest range the view shows (m), the origin of the texture's ``t``;
    ``texture``, ``patches``: texture indices of the fine surface and of the fields.
    """

    height: float
    pitch_deg: float
    roll_deg: float
    slope: tuple[float, float]
    waves: tuple[tuple[float, float, float, float], ...]
    bumps: tuple[tuple[float, float, float, float], ...]
    hill: tuple[float, float, float]
    rim: tuple[float, tuple[tuple[float, float, float], ...]]
    near: float
    texture: int
    patches: int

    @property
    def R_cg(self) -> np.ndarray:
        """(3, 3) ground frame -> left camera frame."""
        return rot_z(np.radians(self.roll_deg)) @ rot_x(np.radians(self.pitch_deg))

    def to_camera(self, X: np.ndarray) -> np.ndarray:
        """Ground-frame points (..., 3) in the left camera's frame."""
        return np.asarray(X, float) @ self.R_cg.T

    def to_ground(self, X: np.ndarray) -> np.ndarray:
        """Left-camera-frame points or directions (..., 3) in the ground frame."""
        return np.asarray(X, float) @ self.R_cg

    def elevation(self, X: np.ndarray | float, Z: np.ndarray | float) -> np.ndarray:
        """e(X, Z), m above the datum (up)."""
        e = np.asarray(self.slope[0] * X + self.slope[1] * Z)
        for a, kx, kz, ph in self.waves:
            e = e + a * np.sin(kx * X + kz * Z + ph)
        for b, x0, z0, s in self.bumps:
            e = e + b * np.exp(-((X - x0) ** 2 + (Z - z0) ** 2) / (2 * s * s))
        rise, z0, width = self.hill
        if rise:
            e = e + rise * _smoothstep((Z - z0) / width)
        return e

    def gradient(self, X: np.ndarray | float, Z: np.ndarray | float
                 ) -> tuple[np.ndarray, np.ndarray]:
        """(dE/dX, dE/dZ) at (X, Z)."""
        gx = np.full(np.shape(X), self.slope[0])
        gz = np.full(np.shape(Z), self.slope[1])
        for a, kx, kz, ph in self.waves:
            c = a * np.cos(kx * X + kz * Z + ph)
            gx = gx + kx * c
            gz = gz + kz * c
        for b, x0, z0, s in self.bumps:
            g = -b * np.exp(-((X - x0) ** 2 + (Z - z0) ** 2) / (2 * s * s)) / (s * s)
            gx = gx + (X - x0) * g
            gz = gz + (Z - z0) * g
        rise, z0, width = self.hill
        if rise:
            gz = gz + rise / width * _smoothstep_slope((Z - z0) / width)
        return gx, gz

    def slope_bound(self) -> float:
        """A bound on |grad e| (unitless) over the ground in view: the largest found on
        a 1 m grid over the rim's width and the range up to it, doubled (each term's
        own maximum, summed, would be several times larger and slow the march down by
        as much)."""
        z_rim, _ = self.rim
        Z = np.arange(0.0, min(z_rim, 20 * self.near), 1.0)
        half = 0.2 * Z[-1]  # 6 deg of view and the roll, with room to spare
        X = np.arange(-half, half, 1.0)
        gx, gz = self.gradient(*np.meshgrid(X, Z))
        return 2.0 * float(np.max(np.hypot(gx, gz)))

    def rim_z(self, X: np.ndarray) -> np.ndarray:
        """Z (m) where the ground ends above ``X``."""
        z0, waves = self.rim
        out = np.full(np.shape(X), z0)
        for a, k, ph in waves:
            out = out + a * np.sin(k * X + ph)
        return out

    def above(self, o: np.ndarray, d: np.ndarray, t: np.ndarray) -> np.ndarray:
        """F(t): how far the ray points ``o + t d`` (ground frame) lie above the ground
        (negative above, m along Y)."""
        X, Y, Z = (o[i] + t * d[..., i] for i in range(3))
        return Y - self.height + self.elevation(X, Z)

    def hits(self, o_cam: np.ndarray, d_cam: np.ndarray, t0: np.ndarray) -> np.ndarray:
        """The first hit of rays ``o_cam + t d_cam`` (left camera frame, ``d_cam``
        (..., 3) with unit camera z) with the ground, as ``t`` (...), marched from
        ``t0`` (...), which must lie before it; inf where the ray passes the rim first."""
        shape = np.shape(t0)
        o = self.to_ground(o_cam)
        d = self.to_ground(d_cam).reshape(-1, 3)
        t = np.array(t0, dtype=np.float64).ravel()
        bound = np.abs(d[:, 1]) + self.slope_bound() * np.hypot(d[:, 0], d[:, 2])
        idx = np.arange(t.size)
        F = self.above(o, d, t)
        sky = np.zeros(t.size, bool)
        for _ in range(MARCH_STEPS):  # only the rays still far above the ground
            past = self._past_rim(o, d[idx], t[idx])
            sky[idx[past]] = True
            live = (F < -MARCH_TOL_M) & ~past
            idx, F = idx[live], F[live]
            if not idx.size:
                break
            t[idx] -= F / bound[idx]
            F = self.above(o, d[idx], t[idx])
        return self.refine(o_cam, d_cam, np.where(sky, np.inf, t).reshape(shape))

    def refine(self, o_cam: np.ndarray, d_cam: np.ndarray, t: np.ndarray) -> np.ndarray:
        """From ``t`` (...) a little before each ray's first hit (inf: none) to the hit,
        by Newton's method kept inside a bracket: never back before the last point
        found above the ground, never beyond the first found below it. A start within
        a few metres of the hit, where the ground turns over tens, has no other root
        between. inf where the hit lies beyond the rim."""
        shape = np.shape(t)
        o = self.to_ground(o_cam)
        d = self.to_ground(d_cam).reshape(-1, 3)
        t = np.array(t, dtype=np.float64).ravel()
        out = np.full(t.size, np.inf)
        idx = np.flatnonzero(np.isfinite(t))
        lo = t[idx]
        hi = np.full(lo.size, np.inf)
        x = lo.copy()
        for _ in range(NEWTON_STEPS):  # only the rays not yet on the ground
            dd = d[idx]
            X, Y, Z = (o[i] + x * dd[:, i] for i in range(3))
            F = Y - self.height + self.elevation(X, Z)
            done = np.abs(F) < NEWTON_TOL_M
            out[idx[done]] = x[done]
            keep = ~done
            idx, x, F, lo, hi, dd = idx[keep], x[keep], F[keep], lo[keep], hi[keep], dd[keep]
            if not idx.size:
                break
            lo = np.where(F < 0, x, lo)
            hi = np.where(F > 0, x, hi)
            gx, gz = self.gradient(X[keep], Z[keep])
            slope = dd[:, 1] + gx * dd[:, 0] + gz * dd[:, 2]
            with np.errstate(divide="ignore", invalid="ignore"):
                nxt = x - F / slope
            outside = ~((nxt > lo) & (nxt < hi))  # no slope, or it points out: bisect
            x = np.where(outside, np.where(np.isfinite(hi), 0.5 * (lo + hi), x + 1.0), nxt)
        out[idx] = x  # the last few, within NEWTON_STEPS of bisection
        out[self._past_rim(o, self.to_ground(d_cam).reshape(-1, 3), out)] = np.inf
        return out.reshape(shape)

    def _past_rim(self, o: np.ndarray, d: np.ndarray, t: np.ndarray) -> np.ndarray:
        X, Z = o[0] + t * d[..., 0], o[2] + t * d[..., 2]
        with np.errstate(invalid="ignore"):
            return Z > self.rim_z(X)

    def normal(self, X_cam: np.ndarray) -> np.ndarray:
        """(..., 3): the ground's normal (unnormalised, pointing down into it) at
        left-camera-frame points ``X_cam`` on it, in the left camera's frame."""
        X = self.to_ground(X_cam)
        gx, gz = self.gradient(X[..., 0], X[..., 2])
        return self.to_camera(np.stack([gx, np.ones_like(gx), gz], axis=-1))

    def surface_coords(self, X_cam: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The fine texture's (s, t) and the fields' (X, Z), m, at points on the ground
        (left camera frame, (..., 3)): two (..., 2) arrays."""
        X = self.to_ground(X_cam)
        e = self.elevation(X[..., 0], X[..., 2])
        with np.errstate(divide="ignore", invalid="ignore"):
            t = self.height * np.log(np.maximum(X[..., 2], 1e-3) / self.near) + e
        return np.stack([X[..., 0], t], axis=-1), np.stack([X[..., 0], X[..., 2]], axis=-1)


def _smoothstep(x: np.ndarray | float) -> np.ndarray:
    x = np.clip(x, 0.0, 1.0)
    return x * x * (3 - 2 * x)


def _smoothstep_slope(x: np.ndarray | float) -> np.ndarray:
    x = np.asarray(x)
    inside = (x > 0) & (x < 1)
    return np.where(inside, 6 * x * (1 - x), 0.0)


def matrix_to_euler(R: np.ndarray) -> tuple[float, float, float]:
    """Degrees (x, y, z) with ``euler_to_matrix(x, y, z) == R`` (R = Rz Ry Rx)."""
    y = -np.arcsin(np.clip(R[2, 0], -1.0, 1.0))
    x = np.arctan2(R[2, 1], R[2, 2])
    z = np.arctan2(R[1, 0], R[0, 0])
    return float(np.degrees(x)), float(np.degrees(y)), float(np.degrees(z))


def make_ground(
    params: SynthParams, rng: np.random.Generator, first_texture: int = 0
) -> tuple[Ground, tuple[Box, ...], tuple[Sphere, ...], tuple[TextureMap, ...]]:
    """A random receding ground for ``params`` (``backdrop="ground"``): the ground, the
    boxes (buildings, rocks) and spheres (tree crowns) standing on it, and their
    textures, numbered from ``first_texture`` (the ground's fine texture, its fields,
    then one per shape).

    The left camera sees the datum at ``near`` on its bottom row and at
    ``depth_ratio * near`` on the skyline's row (``params.sky`` of the height below the
    top; the top row where there is no sky), ``distance_m`` being their mean; its pitch
    and height above the datum follow. ``relief`` scales the hills and hollows
    (``relief * distance_m`` m), which are gentle along the rows' direction and broad
    along the range; half the grounds rise into a hillside before the rim."""
    f = params.focal_px
    vh = (params.height - 1) / 2 / f
    v_sky = -vh + 2 * vh * params.sky if params.sky > 0 else -vh
    r = params.depth_ratio
    near = 2 * params.distance_m / (1 + r)
    far = r * near
    tan_a = (vh - r * v_sky) / (r - 1)
    pitch = float(np.degrees(np.arctan(tan_a)))
    c, s = np.cos(np.arctan(tan_a)), np.sin(np.arctan(tan_a))
    height = near * (vh * c + s)
    relief = params.relief * params.distance_m
    span = far - near
    width_far = far * params.width / f  # metres across the view at the far end
    waves = []
    for _ in range(5):
        kx = 2 * np.pi / (rng.uniform(0.3, 2.0) * width_far) * rng.choice([-1, 1])
        kz = 2 * np.pi / (rng.uniform(0.15, 1.0) * span)
        amp = min(rng.uniform(0.05, 0.2) * relief, 0.3 / np.hypot(kx, kz))
        waves.append((float(amp), float(kx), float(kz), float(rng.uniform(0, 2 * np.pi))))
    bumps = []
    for _ in range(4):
        sigma = float(rng.uniform(0.1, 0.3) * span)
        b = float(rng.uniform(-0.6, 0.6) * relief)
        b = float(np.sign(b) * min(abs(b), 0.4 * sigma))
        z0 = float(rng.uniform(near, far))
        bumps.append((b, float(rng.uniform(-0.5, 0.5) * z0 * params.width / f), z0, sigma))
    rising = rng.random() < 0.5
    hill = ((float(rng.uniform(0.2, 0.6) * height), float(near + rng.uniform(0.5, 0.8) * span),
             float(rng.uniform(0.2, 0.5) * span)) if rising else (0.0, far, 1.0))
    rim_waves = tuple((float(rng.uniform(0.005, 0.02) * far),
                       float(2 * np.pi / (rng.uniform(0.3, 1.0) * width_far)),
                       float(rng.uniform(0, 2 * np.pi))) for _ in range(3))
    rim = (float(RIM_NONE * far), rim_waves)
    textures = [
        random_texture(rng, far / f),  # the fine texture, at least 1.2 px per texel far off
        replace(random_texture(rng, 1.0), texel_m=float(rng.uniform(0.8, 2.5))),  # fields
    ]
    ground = Ground(
        height=float(height),
        pitch_deg=pitch,
        roll_deg=float(rng.uniform(-1.5, 1.5)),
        slope=(float(rng.uniform(-0.01, 0.01)), float(rng.uniform(-0.01, 0.02))),
        waves=tuple(waves),
        bumps=tuple(bumps),
        hill=hill,
        rim=rim,
        near=float(near),
        texture=first_texture,
        patches=first_texture + 1,
    )
    if params.sky > 0:
        half_u = (params.width - 1) / 2 / f
        ground = replace(ground, rim=(_rim_at_row(ground, v_sky, half_u), rim_waves))
    boxes, spheres = [], []
    for i in range(params.n_boxes):
        X, Z = _place(ground, rng, near, 0.95 * far, f, params.width)
        half = (float(rng.uniform(0.5, 2.0)), float(rng.uniform(0.5, 2.5)),
                float(rng.uniform(0.5, 2.0)))
        yaw = float(rng.uniform(-40, 40))
        sink = half[1] * 0.2 + float(np.hypot(*ground.gradient(X, Z))) * max(half[0], half[2])
        centre = np.array([X, ground.height - ground.elevation(X, Z) - half[1] + sink, Z])
        boxes.append(Box(tuple(float(v) for v in ground.to_camera(centre)), half,  # type: ignore[arg-type]
                         matrix_to_euler(ground.R_cg @ rot_y(np.radians(yaw))),
                         texture=first_texture + 2 + i))
        textures.append(random_texture(rng, Z / f))
    for i in range(params.n_spheres):
        X, Z = _place(ground, rng, near, 0.95 * far, f, params.width)
        radius = float(rng.uniform(0.5, 2.0))
        centre = np.array([X, ground.height - ground.elevation(X, Z) - 0.8 * radius, Z])
        spheres.append(Sphere(tuple(float(v) for v in ground.to_camera(centre)), radius,  # type: ignore[arg-type]
                              texture=first_texture + 2 + params.n_boxes + i))
        textures.append(random_texture(rng, Z / f))
    return ground, tuple(boxes), tuple(spheres), tuple(textures)


def _rim_at_row(ground: Ground, v: float, half_u: float) -> float:
    """The ground frame's Z where the left view's row at normalised ``v`` sees the
    ground (the median over its columns, ``half_u`` the normalised half width): the
    rim that puts the skyline there."""
    x = np.linspace(-0.9, 0.9, 31) * half_u
    d = np.stack([x, np.full_like(x, v), np.ones_like(x)], axis=1)
    t = ground.hits(np.zeros(3), d, np.full(x.size, 0.3 * ground.near))
    Z = ground.to_ground(t[:, None] * d)[:, 2]
    return float(np.median(Z[np.isfinite(Z)]))


def _place(ground: Ground, rng: np.random.Generator, near: float, far: float, f: float,
           width: int) -> tuple[float, float]:
    """A random ground position (X, Z), m, inside the left view's columns and short of
    the rim (an object beyond it would float in the sky)."""
    Z = float(rng.uniform(near, far))
    X = float(rng.uniform(-0.4, 0.4) * Z * width / f)
    return X, min(Z, 0.97 * float(ground.rim_z(np.array(X))))
