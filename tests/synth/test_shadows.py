"""Cloud shadows: on the surface in 3D, drifting between captures, never in the depth."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from rigkit.synth import SynthParams, generate_scene
from rigkit.synth.changes import SHADOW_CHANGE, shadow_changed_left
from rigkit.synth.render import render_layers
from rigkit.synth.shadows import CloudShadow, shadow_factor

BARE = SynthParams(width=320, height=240, n_boxes=0, n_spheres=0)
# One round shadow over the middle of the view, 60 % of the light left in its core,
# drifting 5 m to the right per capture.
CLOUD = CloudShadow(center=(0.0, 0.0), radii=(8.0, 8.0), angle_deg=0.0, wobble=(),
                    edge_m=4.0, light=0.6, drift=(5.0, 0.0))


def _lift(scene, depth):
    cam = scene.cameras["left"]
    v, u = np.mgrid[0 : cam.height, 0 : cam.width].astype(float)
    return cam.C + cam.rays(u, v) * depth[..., None]


def test_shadow_changes_radiance_not_depth() -> None:
    sunny = generate_scene(BARE, 2)
    cloudy = replace(sunny, shadows=(CLOUD,))
    a, b = render_layers(sunny, "left"), render_layers(cloudy, "left")
    assert np.array_equal(a.depth, b.depth) and np.array_equal(a.surface, b.surface)
    ratio = b.radiance / a.radiance
    assert ratio.min() == pytest.approx(0.6, abs=1e-4) and ratio.max() == pytest.approx(1.0)
    assert 0.1 < np.mean(ratio < 0.61) < 0.6  # a core in the middle ...
    assert np.abs(np.diff(ratio, axis=1)).max() < 0.03  # ... with soft edges


def test_shadow_belongs_to_the_surface_and_drifts_between_captures() -> None:
    scene = replace(generate_scene(BARE, 2), shadows=(CLOUD,))
    X = _lift(scene, render_layers(scene, "left").depth)
    args = (scene.light, scene.params.distance_m)
    # At capture k the shadow has moved k * drift: a point sees in the right view what
    # the point 5 m to its left saw in the left view, in the back view 10 m to its left.
    for view, k in (("right", 1), ("back", 2)):
        moved_back = X - np.array([5.0 * k, 0.0, 0.0])
        assert np.allclose(shadow_factor(scene.shadows, X, view, *args),
                           shadow_factor(scene.shadows, moved_back, "left", *args), atol=1e-6)
    # The right camera sees a left pixel's surface point under the right view's shadow.
    sunny = replace(scene, shadows=())
    right, right_sunny = render_layers(scene, "right"), render_layers(sunny, "right")
    uv, _ = scene.cameras["right"].project(X)
    ui, vi = np.rint(uv[..., 0]).astype(int), np.rint(uv[..., 1]).astype(int)
    ok = (ui >= 0) & (ui < 320) & (vi >= 0) & (vi < 240)
    seen = right.radiance[vi[ok], ui[ok]] / right_sunny.radiance[vi[ok], ui[ok]]
    predicted = shadow_factor(scene.shadows, X[ok], "right", *args)
    assert np.median(np.abs(seen - predicted)) < 0.005


def test_shadow_changed_mask_is_where_the_factor_differs() -> None:
    scene = replace(generate_scene(BARE, 2), shadows=(CLOUD,))
    depth = render_layers(scene, "left").depth
    changed = shadow_changed_left(scene, depth)
    assert 0.05 < changed.mean() < 0.9
    X = _lift(scene, depth)
    args = (scene.light, scene.params.distance_m)
    left = shadow_factor(scene.shadows, X, "left", *args)
    diff = np.maximum(*(np.abs(shadow_factor(scene.shadows, X, v, *args) - left)
                        for v in ("right", "back")))
    assert np.array_equal(changed, diff > SHADOW_CHANGE)
    still = replace(scene, shadows=(replace(CLOUD, drift=(0.0, 0.0)),))
    assert not shadow_changed_left(still, depth).any()  # a shadow that stays changes nothing


def test_generated_shadows_are_as_documented() -> None:
    scene = generate_scene(replace(BARE, n_shadows=20, shadow_drift_m=7.0), 4)
    assert len(scene.shadows) == 20
    for s in scene.shadows:
        assert 0.4 <= s.light <= 0.7 and np.hypot(*s.drift) == pytest.approx(7.0)
        assert 0.15 <= s.edge_m / np.sqrt(s.radii[0] * s.radii[1]) <= 0.5
