"""Things that move between the three captures: cars and people (``SynthParams.n_movers``).

The views are taken minutes apart, so a car or a walker seen in one view is somewhere
else, or gone, in the next. Each mover is in each view with probability 0.7 (in at
least one), and is placed independently in every view that has it: anywhere in the left
camera's view, below the skyline, on a heading of its own (cars mostly sideways, as on a
road across the slope; people any way), standing 0.5-3 m clear in front of the terrain.
Half of them are cars: a body 3.8-4.9 m long, 1.7-1.9 m wide, 0.75-0.95 m high, with a
cabin on top (0.5-0.65 m); the others people: 1.55-1.95 m tall, 0.4-0.55 m wide, a box
for the body and one for the head. Each wears a :class:`Paint`, the same in every view:
a paint (or clothing) albedo of its own with a photograph's detail on it, so that it
stands out from the terrain as real cars and people do, yet has texture to match.
At 300 m and the paper's 6 deg view (43,963 px focal length at 4608 px) a 4.5 m car is
~660 px long and a person ~260 px tall; at 640 px width, 92 and 36 px.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from rigkit.geometry import euler_to_matrix
from rigkit.synth.shapes import VIEWS, Box, Terrain, TextureMap, random_texture

PRESENCE = 0.7  # probability that a mover is in a given view
Part = tuple[tuple[float, float, float], tuple[float, float, float]]


@dataclass(frozen=True)
class Paint:
    """A mover's look: albedo ``albedo * (0.5 + photo)`` (clipped to 1), ``photo`` being
    ``texture``'s value in [0.02, 1] at the surface point."""

    texture: TextureMap
    albedo: float


def painted(paint: Paint, photo: np.ndarray) -> np.ndarray:
    """Albedo (float32, shape of ``photo``) of ``paint`` where its texture is ``photo``."""
    return np.minimum(paint.albedo * (0.5 + photo), 1.0).astype(np.float32)


@dataclass(frozen=True)
class Mover:
    """A car or a person. ``parts``: (centre, half extents) of each box in the mover's
    own axes (m; x along its heading, y down, z across; origin at the middle of its
    base). ``poses``: view name -> (x, y, z, yaw_deg), the origin in the world (left
    camera frame, m) and the turn about the vertical y axis when that view was taken;
    a view with no entry does not see the mover."""

    kind: str
    parts: tuple[Part, ...]
    texture: int
    poses: dict[str, tuple[float, float, float, float]] = field(default_factory=dict)

    def boxes(self, view: str) -> tuple[Box, ...]:
        """The mover's boxes in world coordinates as ``view`` sees it (none if absent)."""
        pose = self.poses.get(view)
        if pose is None:
            return ()
        x, y, z, yaw = pose
        R = euler_to_matrix(0.0, yaw, 0.0)  # mover axes -> world
        out = []
        for centre, half in self.parts:
            c = np.array([x, y, z]) + R @ np.array(centre)
            out.append(Box((float(c[0]), float(c[1]), float(c[2])), half, (0.0, yaw, 0.0),
                           self.texture))
        return tuple(out)

    def size(self) -> tuple[float, float, float]:
        """(length, height, width), m: the extent of its parts along its own axes."""
        lo = np.min([np.subtract(c, h) for c, h in self.parts], axis=0)
        hi = np.max([np.add(c, h) for c, h in self.parts], axis=0)
        return float(hi[0] - lo[0]), float(hi[1] - lo[1]), float(hi[2] - lo[2])


def _car(rng: np.random.Generator) -> tuple[Part, ...]:
    length, width = rng.uniform(3.8, 4.9), rng.uniform(1.7, 1.9)
    body_h, cabin_h = rng.uniform(0.75, 0.95), rng.uniform(0.5, 0.65)
    cabin_len, cabin_x = length * rng.uniform(0.45, 0.6), length * rng.uniform(-0.12, 0.02)
    body = ((0.0, -body_h / 2, 0.0), (length / 2, body_h / 2, width / 2))
    cabin = ((cabin_x, -body_h - cabin_h / 2, 0.0), (cabin_len / 2, cabin_h / 2, 0.46 * width))
    return _floats(body), _floats(cabin)


def _person(rng: np.random.Generator) -> tuple[Part, ...]:
    height, width, depth, head = (rng.uniform(1.55, 1.95), rng.uniform(0.4, 0.55),
                                  rng.uniform(0.25, 0.35), 0.23)
    body_h = height - head
    body = ((0.0, -body_h / 2, 0.0), (width / 2, body_h / 2, depth / 2))
    top = ((0.0, -height + head / 2, 0.0), (0.4 * head, head / 2, head / 2))
    return _floats(body), _floats(top)


def _floats(part: tuple[tuple, tuple]) -> Part:
    c, h = part
    return (float(c[0]), float(c[1]), float(c[2])), (float(h[0]), float(h[1]), float(h[2]))


def _pose(
    mover: Mover, terrain: Terrain, half_w: float, half_h: float, rng: np.random.Generator
) -> tuple[float, float, float, float]:
    """A random place for ``mover`` in the left view, clear in front of the terrain."""
    length, height, width = mover.size()
    yaw = float(rng.uniform(-30, 30) + 180 * rng.integers(2) if mover.kind == "car"
                else rng.uniform(0, 360))
    c, s = abs(np.cos(np.radians(yaw))), abs(np.sin(np.radians(yaw)))
    ext_x, ext_z = c * length / 2 + s * width / 2, s * length / 2 + c * width / 2
    x = float(rng.uniform(-0.85, 0.85) * half_w)
    xs = x + np.linspace(-ext_x, ext_x, 5)
    top = max(-0.85 * half_h, float(np.max(terrain.skyline_y(xs))) + 0.2)
    highest_base = top + height  # y grows downwards: the base is at least this low
    y = float(rng.uniform(highest_base, max(highest_base, 0.9 * half_h)))
    gx, gy = np.meshgrid(xs, np.linspace(y - height, y, 5))
    z = float(np.min(terrain.z(gx, gy)) - rng.uniform(0.5, 3.0) - ext_z)
    return x, y, z, yaw


def make_movers(
    n: int,
    terrain: Terrain,
    half_w: float,
    half_h: float,
    pixel_m: float,
    first_texture: int,
    rng: np.random.Generator,
) -> tuple[tuple[Mover, ...], tuple[Paint, ...]]:
    """``n`` movers over the left view (``half_w``, ``half_h``: half its width and height
    at the terrain, m; ``pixel_m``: a pixel there, m), with their textures numbered from
    ``first_texture``."""
    movers: list[Mover] = []
    textures: list[Paint] = []
    for i in range(n):
        kind = "car" if rng.random() < 0.5 else "person"
        parts = _car(rng) if kind == "car" else _person(rng)
        paint = rng.uniform(0.05, 0.85) if kind == "car" else rng.uniform(0.08, 0.7)
        textures.append(Paint(random_texture(rng, pixel_m), float(paint)))
        present = rng.random(3) < PRESENCE
        if not present.any():
            present[rng.integers(3)] = True
        mover = Mover(kind, parts, first_texture + i)
        views = [v for v, p in zip(VIEWS, present, strict=True) if p]
        movers.append(replace(mover, poses={v: _pose(mover, terrain, half_w, half_h, rng)
                                            for v in views}))
    return tuple(movers), tuple(textures)
