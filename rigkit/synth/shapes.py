"""The analytic shapes a synthetic scene is built from (metres, in the left camera's
frame: x right, y down, z forward) and the photographic texture they wear.

A terrain-like surface ``z = g(x, y)`` facing the cameras, oriented boxes and spheres
standing in front of it; :mod:`rigkit.synth.render` casts rays at them exactly.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

VIEWS = ("left", "right", "back")  # the three camera positions, in the order they are taken

# Surface coordinates of box face k (0..5: axis * 2 + (normal along +axis)) are the two
# other box-axis coordinates shifted by k * FACE_SHIFT (m), so that no two faces of a box
# show the same patch of texture.
FACE_SHIFT = (7.3, -5.1)
FRONT_FACE = 4  # the face whose normal is the box's -z axis: towards the cameras


@dataclass(frozen=True)
class Terrain:
    """``z = base + sx*x + sy*y + sum A sin(kx x + ky y + phase) + sum B exp(-r^2 / 2 s^2)``."""

    base: float
    slope: tuple[float, float]
    waves: tuple[tuple[float, float, float, float], ...]  # (A, kx, ky, phase)
    bumps: tuple[tuple[float, float, float, float], ...]  # (B, x0, y0, sigma)
    texture: int
    # Skyline y_s(x) = y0 + sum A sin(k x + phase), as (y0, ((A, k, phase), ...)): the
    # surface ends above it (y < y_s, y down); None = it fills the view.
    skyline: tuple[float, tuple[tuple[float, float, float], ...]] | None = None

    def skyline_y(self, x: np.ndarray) -> np.ndarray:
        """y (m, down) of the skyline above ``x`` (m); -inf where there is none."""
        if self.skyline is None:
            return np.full(np.shape(x), -np.inf)
        y0, waves = self.skyline
        ys = np.full(np.shape(x), y0)
        for a, k, ph in waves:
            ys = ys + a * np.sin(k * x + ph)
        return ys

    def above_skyline(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        """True where the surface point ``(x, y)`` (m, left frame) is cut away (sky)."""
        if self.skyline is None:
            return np.zeros(np.shape(x), bool)
        return y < self.skyline_y(x)

    def z(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        out = self.base + self.slope[0] * x + self.slope[1] * y
        for a, kx, ky, ph in self.waves:
            out = out + a * np.sin(kx * x + ky * y + ph)
        for b, x0, y0, s in self.bumps:
            out = out + b * np.exp(-((x - x0) ** 2 + (y - y0) ** 2) / (2 * s * s))
        return out

    def gradient(self, x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        gx = np.full_like(x, self.slope[0])
        gy = np.full_like(y, self.slope[1])
        for a, kx, ky, ph in self.waves:
            c = a * np.cos(kx * x + ky * y + ph)
            gx = gx + kx * c
            gy = gy + ky * c
        for b, x0, y0, s in self.bumps:
            e = b * np.exp(-((x - x0) ** 2 + (y - y0) ** 2) / (2 * s * s)) / (s * s)
            gx = gx - (x - x0) * e
            gy = gy - (y - y0) * e
        return gx, gy


@dataclass(frozen=True)
class Box:
    """An oriented box: centre (m), half extents (m) along its own axes, orientation as
    Euler angles (box axes -> world = ``euler_to_matrix(*euler_deg)``), texture index."""

    center: tuple[float, float, float]
    half: tuple[float, float, float]
    euler_deg: tuple[float, float, float]
    texture: int


@dataclass(frozen=True)
class Sphere:
    center: tuple[float, float, float]
    radius: float
    texture: int


@dataclass(frozen=True)
class TextureMap:
    """Which photograph a surface wears, at what scale (m per texel), rotation and offset."""

    photo: str
    texel_m: float
    angle_deg: float
    offset: tuple[float, float]
    noise_seed: int


PHOTOS = (
    "astronaut",
    "camera",
    "coffee",
    "chelsea",
    "rocket",
    "brick",
    "grass",
    "gravel",
    "moon",
    "coins",
    "text",
)


def random_texture(rng: np.random.Generator, pixel_m: float) -> TextureMap:
    """A photograph from ``PHOTOS`` at 1.2-2 pixels per texel (``pixel_m``: the size of
    one pixel at the scene distance, m), turned and shifted at random."""
    return TextureMap(
        photo=PHOTOS[int(rng.integers(len(PHOTOS)))],
        texel_m=float(pixel_m * rng.uniform(1.2, 2.0)),
        angle_deg=float(rng.uniform(0, 360)),
        offset=(float(rng.uniform(0, 400)), float(rng.uniform(0, 400))),
        noise_seed=int(rng.integers(2**31)),
    )
