"""Ground receding up the view (synth/ground.py): exact first hits, the depths asked
for, objects standing on the ground, and the rim with sky above it."""

from __future__ import annotations

import numpy as np
import pytest

from rigkit.errors import InputError
from rigkit.synth import SynthParams, generate_scene
from rigkit.synth.ground import Ground
from rigkit.synth.render import render_layers

PARAMS = SynthParams(width=320, height=240, backdrop="ground", depth_ratio=1.8, sky=0.3)


@pytest.fixture(scope="module")
def scene():
    return generate_scene(PARAMS, 5)


@pytest.fixture(scope="module")
def left(scene):
    return render_layers(scene, "left")


def _first_root(ground: Ground, o: np.ndarray, d: np.ndarray) -> float:
    """The first hit along one ray by brute force: F sampled every 2 cm."""
    t = np.arange(1.0, 3000.0, 0.02)
    og, dg = ground.to_ground(o), ground.to_ground(d)
    F = ground.above(og, np.broadcast_to(dg, (t.size, 3)), t)
    X, Z = og[0] + t * dg[0], og[2] + t * dg[2]
    cross = np.flatnonzero((F[:-1] < 0) & (F[1:] >= 0) & (Z[1:] <= ground.rim_z(X[1:])))
    return float(t[cross[0] + 1]) if cross.size else np.inf


def test_the_renderer_finds_each_rays_first_hit(scene, left) -> None:
    ground = scene.terrain
    assert isinstance(ground, Ground)
    rng = np.random.default_rng(0)
    ground_px = np.argwhere(left.surface == 0)
    sky_px = np.argwhere(left.surface < 0)
    assert len(ground_px) and len(sky_px)  # both in view
    for v, u in [*ground_px[rng.choice(len(ground_px), 60)], *sky_px[rng.choice(len(sky_px), 20)]]:
        ray = scene.cameras["left"].rays(np.array(float(u)), np.array(float(v)))
        truth = _first_root(ground, scene.cameras["left"].C, ray)
        seen = left.depth[v, u]
        if np.isfinite(truth):
            assert seen == pytest.approx(truth, abs=0.03)  # the brute force's step
        else:
            assert np.isnan(seen)


def test_the_view_spans_the_depths_asked_for(scene, left) -> None:
    ground = left.depth[left.surface == 0]
    near, far = np.percentile(ground, [0.5, 99.5])
    asked = 2 * PARAMS.distance_m / (1 + PARAMS.depth_ratio)  # the datum's, bottom row
    assert near == pytest.approx(asked, rel=0.2)  # the hills move the nearest ground
    assert far / near > 1.3
    sky = np.isnan(left.depth).mean()
    assert 0.1 < sky < 0.45  # the rim about 30 % of the height below the top


def test_objects_stand_on_the_ground(scene) -> None:
    ground = scene.terrain
    for box in scene.boxes:
        c = ground.to_ground(np.array(box.center))
        floor = ground.height - ground.elevation(c[0], c[2])  # the ground's Y below it
        # the box's centre sits above the ground by less than its height, not floating
        assert 0 < floor - c[1] < 2 * max(box.half)
    for sphere in scene.spheres:
        c = ground.to_ground(np.array(sphere.center))
        floor = ground.height - ground.elevation(c[0], c[2])
        assert floor - c[1] == pytest.approx(0.8 * sphere.radius, rel=1e-6)


def test_the_same_seed_gives_the_same_ground() -> None:
    assert generate_scene(PARAMS, 5).terrain == generate_scene(PARAMS, 5).terrain


def test_the_ground_has_no_movers_or_facades() -> None:
    from dataclasses import replace

    with pytest.raises(InputError, match="movers and facades"):
        generate_scene(replace(PARAMS, n_movers=2), 1)
