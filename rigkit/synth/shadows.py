"""Cloud shadows that drift between the three captures (``SynthParams.n_shadows``).

A cloud's shadow is the cloud's outline projected along the sunlight onto the scene, so
it belongs to the 3D surface, not to the image: the shadow factor of a surface point X
is looked up at X's projection along the light direction ``L`` (``Scene.light``, from
the surface towards the sun) onto the plane ``z = z0`` (the scene distance):

    P(X) = X - (X_z - z0) / L_z * L          (only P_x, P_y are used)

Each shadow is a soft-edged blob on that plane: with ``(u, v)`` the offset of ``P``
from its centre in the blob's own axes, ``phi`` its polar angle and ``rho`` the
elliptical radius ``sqrt((u/a)^2 + (v/b)^2) / (1 + sum A_n cos(n phi + phase_n))``
(a few low harmonics make the outline cloud-like), its coverage is 1 inside
``rho < 1 - h``, 0 outside ``rho > 1 + h`` and a smoothstep in between, ``h`` being
half the edge width over the mean radius ``sqrt(a b)``. The light that remains is
``1 - (1 - light) * coverage``, with ``light`` 0.4-0.7; where shadows overlap the
darkest wins. Between captures the clouds drift: at capture ``k`` (0 left, 1 right, 2
back, the order the views are taken in) a blob's centre has moved by ``k * drift``.
The factor multiplies the surface's radiance (direct and sky light alike) before haze.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from rigkit.synth.shapes import VIEWS


@dataclass(frozen=True)
class CloudShadow:
    """One drifting cloud shadow. Lengths in metres on the shadow plane (x right, y
    down); ``angle_deg`` turns the blob's axes from x, y; ``wobble`` is the outline's
    harmonics ``(A_n, n, phase_n)``; ``drift`` the centre's move per capture."""

    center: tuple[float, float]
    radii: tuple[float, float]
    angle_deg: float
    wobble: tuple[tuple[float, int, float], ...]
    edge_m: float
    light: float
    drift: tuple[float, float]


def shadow_plane(X: np.ndarray, light: tuple[float, float, float], z0: float) -> np.ndarray:
    """(..., 2) float64: where world points ``X`` (..., 3, m) fall on the shadow plane."""
    L = np.asarray(light, float) / np.linalg.norm(light)
    s = (X[..., 2] - z0) / L[2]
    return X[..., :2] - s[..., None] * L[:2]


def _coverage(shadow: CloudShadow, P: np.ndarray, capture: int) -> np.ndarray:
    """(...) float64 in [0, 1]: how much of the sun ``shadow`` hides at plane points P."""
    c = np.asarray(shadow.center) + capture * np.asarray(shadow.drift)
    a = np.radians(shadow.angle_deg)
    dx, dy = P[..., 0] - c[0], P[..., 1] - c[1]
    u = np.cos(a) * dx + np.sin(a) * dy
    v = -np.sin(a) * dx + np.cos(a) * dy
    phi = np.arctan2(v, u)
    outline = np.ones_like(phi)
    for amp, n, phase in shadow.wobble:
        outline = outline + amp * np.cos(n * phi + phase)
    rho = np.hypot(u / shadow.radii[0], v / shadow.radii[1]) / outline
    h = shadow.edge_m / (2 * np.sqrt(shadow.radii[0] * shadow.radii[1]))
    x = np.clip((1 + h - rho) / (2 * h), 0, 1)
    return x * x * (3 - 2 * x)


def shadow_factor(
    shadows: tuple[CloudShadow, ...],
    X: np.ndarray,
    view: str,
    light: tuple[float, float, float],
    z0: float,
) -> np.ndarray:
    """(...) float32 in (0, 1]: the light that reaches world points ``X`` (..., 3, m)
    when ``view`` is captured (1 = no shadow)."""
    P = shadow_plane(X, light, z0)
    k = VIEWS.index(view)
    out = np.ones(X.shape[:-1])
    for s in shadows:
        out = np.minimum(out, 1 - (1 - s.light) * _coverage(s, P, k))
    return out.astype(np.float32)


def make_shadows(
    n: int, half_w: float, drift_m: float, rng: np.random.Generator
) -> tuple[CloudShadow, ...]:
    """``n`` cloud shadows over a view ``2 half_w`` (m) wide at the scene: mean radius
    0.3-1 of ``half_w``, soft edges 15-50 % of it, centres within the view, drifting
    ``drift_m`` per capture in a random direction."""
    out = []
    for _ in range(n):
        r = float(rng.uniform(0.3, 1.0) * half_w)
        aspect = float(rng.uniform(0.6, 1.0))
        centre = rng.uniform(-half_w, half_w, 2)
        wobble = tuple(
            (float(rng.uniform(0.0, 0.12)), n_h, float(rng.uniform(0, 2 * np.pi)))
            for n_h in (2, 3, 5)
        )
        heading = rng.uniform(0, 2 * np.pi)
        out.append(
            CloudShadow(
                center=(float(centre[0]), float(centre[1])),
                radii=(float(r / np.sqrt(aspect)), float(r * np.sqrt(aspect))),
                angle_deg=float(rng.uniform(0, 180)),
                wobble=wobble,
                edge_m=float(rng.uniform(0.15, 0.5) * r),
                light=float(rng.uniform(0.4, 0.7)),
                drift=(float(drift_m * np.cos(heading)), float(drift_m * np.sin(heading))),
            )
        )
    return tuple(out)
