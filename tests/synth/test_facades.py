"""Facades: strictly periodic windows on a plain wall, and plain walls."""

from __future__ import annotations

from dataclasses import replace

import cv2
import numpy as np
import pytest

from rigkit.errors import InputError
from rigkit.synth import SynthParams, generate_scene
from rigkit.synth.facades import FacadeLook, facade_albedo
from rigkit.synth.render import render_layers

BARE = SynthParams(width=640, height=480, n_boxes=0, n_spheres=0)


def _head_on(seed: int):
    """A bare scene with two generated facades, turned to face the cameras and moved
    apart: the first has windows, the second is plain."""
    scene = generate_scene(replace(BARE, n_facades=2), seed)
    boxes = tuple(replace(b, euler_deg=(0.0, 0.0, 0.0)) for b in scene.boxes)
    return replace(scene, boxes=boxes), boxes[0]


def test_windows_repeat_with_the_facade_period() -> None:
    scene, box = _head_on(6)
    look = scene.textures[box.texture]
    assert isinstance(look, FacadeLook) and look.period is not None
    (ps, pt), (ws, wt) = look.period, look.window
    s = look.origin[0] + np.linspace(0.0, 10 * ps, 10001)[:-1]  # ten whole periods
    t = np.full_like(s, look.origin[1] + pt / 2)  # along the middle of a storey
    a = facade_albedo(look, s, t)
    assert np.array_equal(a, facade_albedo(look, s + 3 * ps, t + 2 * pt))
    assert set(np.unique(a)) == {np.float32(look.wall), np.float32(look.glass)}
    assert np.mean(a == np.float32(look.glass)) == pytest.approx(ws / ps, abs=0.01)
    column = facade_albedo(look, np.full_like(s, look.origin[0] + ps / 2),
                           look.origin[1] + np.linspace(0.0, 10 * pt, 10001)[:-1])
    assert np.mean(column == np.float32(look.glass)) == pytest.approx(wt / pt, abs=0.01)
    # In the image: along a row through a storey's windows, on the front face,
    # dark runs start once per period (the period's length in pixels at that depth).
    layers = render_layers(replace(scene, boxes=(box,)), "left")
    cam = scene.cameras["left"]
    cx, cy, cz = box.center
    front = cz - box.half[2]
    storey = int(box.half[1] / pt)  # the middle one
    (_, v), _ = cam.project(np.array([cx, cy - box.half[1] + (storey + 0.5) * pt, front]))
    r = int(round(v))
    on_face = (layers.surface[r] == box.texture) & (np.abs(layers.depth[r] - front) < 1e-3)
    cols = np.flatnonzero(on_face)
    assert len(cols) > 3 * ps * cam.f / front and np.all(np.diff(cols) == 1)
    row = layers.radiance[r, cols]
    dark = row < (row.max() + row.min()) / 2
    starts = np.flatnonzero(dark[1:] & ~dark[:-1])
    period_px = ps * cam.f / front
    assert len(starts) >= 2
    assert np.allclose(np.diff(starts), period_px, atol=1.5)
    whole = dark[starts[0] : starts[-1]]  # whole periods
    assert np.mean(whole) == pytest.approx(ws / ps, abs=0.05)


def test_plain_wall_has_no_texture_at_all() -> None:
    scene, _ = _head_on(6)
    plain = scene.boxes[1]
    look = scene.textures[plain.texture]
    assert isinstance(look, FacadeLook) and look.period is None
    layers = render_layers(scene, "left")
    front = plain.center[2] - plain.half[2]  # the face towards the cameras, at one depth
    face = (layers.surface == plain.texture) & (np.abs(layers.depth - front) < 1e-3)
    assert face.sum() > 1000 and np.ptp(layers.radiance[face]) < 1e-6  # one shade


def test_generated_facades_have_building_sizes() -> None:
    scene = generate_scene(replace(BARE, n_facades=6), 1)
    looks = [scene.textures[b.texture] for b in scene.boxes]
    assert [lk.period is None for lk in looks] == [False, True] * 3  # type: ignore[union-attr]
    for box, look in zip(scene.boxes, looks, strict=True):
        assert isinstance(look, FacadeLook)
        assert box.half[0] >= 1.5 * 1.5 and abs(box.euler_deg[1]) <= 20
        if look.period is not None:
            ps, pt = look.period
            assert 1.5 <= ps <= 3.5 and 3.0 <= pt <= 3.6
            assert (2 * box.half[0] / ps) % 1 == pytest.approx(0) or (
                2 * box.half[0] / ps) % 1 == pytest.approx(1)  # whole columns


def test_flat_mask_marks_the_plain_wall_and_not_the_terrain() -> None:
    scene, _ = _head_on(6)
    plain = scene.boxes[1]
    layers = render_layers(scene, "left")
    flat = layers.flat()
    inner = cv2.erode((layers.surface == plain.texture).astype(np.uint8),
                      np.ones((15, 15), np.uint8)) > 0
    assert inner.sum() > 500 and flat[inner].all()
    terrain = cv2.erode((layers.surface == 0).astype(np.uint8), np.ones((15, 15), np.uint8)) > 0
    assert flat[terrain].mean() < 0.01
    assert not flat[~np.isfinite(layers.depth)].any()  # no surface is not a flat surface


def test_void_backdrop_is_black_with_no_ground() -> None:
    scene = generate_scene(replace(BARE, backdrop="void"), 2)
    layers = render_layers(scene, "left")
    empty = ~np.isfinite(layers.depth)
    assert empty.mean() > 0.2 and (layers.surface[empty] == -1).all()
    assert np.all(layers.radiance[empty] == 0.0)
    assert not (layers.surface == 0).any()  # the terrain is gone
    with pytest.raises(InputError, match="backdrop=.mist."):
        replace(BARE, backdrop="mist").validate()
