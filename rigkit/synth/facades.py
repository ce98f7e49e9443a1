"""Building facades: the hard cases for stereo matching (``SynthParams.n_facades``).

A facade is a box (a building) standing in front of the terrain, nearly facing the
cameras, that wears a :class:`FacadeLook` instead of a photograph: either a plain wall
of one albedo (no texture at all to match) or a wall with a strictly periodic grid of
windows (a pattern that also matches one or more window periods away). Facades
alternate: the first, third, ... have windows, the second, fourth, ... are plain.
Sizes are those of real buildings: window columns 1.5-3.5 m apart, storeys 3-3.6 m.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from rigkit.synth.shapes import FACE_SHIFT, FRONT_FACE, Box, Terrain


@dataclass(frozen=True)
class FacadeLook:
    """Albedo of a facade in its surface coordinates ``(s, t)`` (m; s along the box's
    x axis, t along its y axis, i.e. down). ``period`` (m) is the window grid's spacing
    along s and t, None for a plain wall; ``window`` (m) the size of one window, centred
    in its cell; ``origin`` (m) a corner of the grid, where the front face begins."""

    wall: float
    glass: float
    period: tuple[float, float] | None
    window: tuple[float, float]
    origin: tuple[float, float]


def facade_albedo(look: FacadeLook, s: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Albedo (same shape as ``s``, float32 in [0, 1]) at surface coordinates (m)."""
    if look.period is None:
        return np.full(np.shape(s), look.wall, np.float32)
    (ps, pt), (ws, wt) = look.period, look.window
    cs = np.mod(s - look.origin[0], ps) - ps / 2  # position in the cell, from its centre
    ct = np.mod(t - look.origin[1], pt) - pt / 2
    glass = (np.abs(cs) < ws / 2) & (np.abs(ct) < wt / 2)
    return np.where(glass, look.glass, look.wall).astype(np.float32)


def _front_origin(half: tuple[float, float, float]) -> tuple[float, float]:
    """Surface coordinates of the front face's top-left corner (see ``FACE_SHIFT``)."""
    return (-half[0] + FRONT_FACE * FACE_SHIFT[0], -half[1] + FRONT_FACE * FACE_SHIFT[1])


def make_facades(
    n: int,
    terrain: Terrain,
    half_w: float,
    half_h: float,
    relief_m: float,
    first_texture: int,
    rng: np.random.Generator,
) -> tuple[tuple[Box, ...], tuple[FacadeLook, ...]]:
    """``n`` facade boxes in front of ``terrain`` within the left view (``half_w``,
    ``half_h``: half its width and height at the terrain, m), their looks numbered
    from texture index ``first_texture``."""
    boxes, looks = [], []
    for i in range(n):
        ps, pt = float(rng.uniform(1.5, 3.5)), float(rng.uniform(3.0, 3.6))
        cols = int(rng.integers(3, max(4, int(1.2 * half_w / ps)) + 1))
        rows = int(rng.integers(2, max(3, int(1.2 * half_h / pt)) + 1))
        half = (cols * ps / 2, rows * pt / 2, float(rng.uniform(3.0, 8.0)))
        x, y = rng.uniform(-0.7, 0.7) * half_w, rng.uniform(-0.6, 0.6) * half_h
        gap = rng.uniform(0.3, 1.0) * max(relief_m, 1.0)
        z = float(terrain.z(np.array(x), np.array(y))) - half[2] - gap
        yaw = float(rng.uniform(-20, 20))
        boxes.append(Box((float(x), float(y), z), half, (0.0, yaw, 0.0), first_texture + i))
        wall = float(rng.uniform(0.45, 0.85))
        window = (ps * float(rng.uniform(0.4, 0.65)), pt * float(rng.uniform(0.4, 0.6)))
        period = (ps, pt) if i % 2 == 0 else None
        glass = float(rng.uniform(0.05, 0.2))
        looks.append(FacadeLook(wall, glass, period, window, _front_origin(half)))
    return tuple(boxes), tuple(looks)
