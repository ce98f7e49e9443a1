"""Movers and the moved mask, checked against placements known in advance."""

from __future__ import annotations

from dataclasses import replace

import cv2
import numpy as np
import pytest

from rigkit.synth import SynthParams, generate_scene
from rigkit.synth.changes import moved_left
from rigkit.synth.movers import Mover, Paint
from rigkit.synth.render import box_hits, render_layers
from rigkit.synth.shapes import Box, TextureMap

BARE = SynthParams(width=320, height=240, n_boxes=0, n_spheres=0)
CAR_Z = 290.0  # origin of the test car; its front face is 0.9 m nearer
CAR = ((0.0, -0.75, 0.0), (2.25, 0.75, 0.9))  # one box: 4.5 m long, 1.5 m high, 1.8 m wide


def _scene_with_car(poses: dict, static: tuple[Box, ...] = ()):
    """A bare seed-3 scene with one car (``poses``: view -> (x, y, z, yaw)) and the given
    static boxes, which wear texture 2; returns the scene and the car's texture (1)."""
    scene = generate_scene(BARE, 3)
    assert len(scene.textures) == 1  # the terrain's
    grass = TextureMap("grass", 0.05, 0.0, (0.0, 0.0), 1)
    car = Mover("car", (CAR,), 1, poses)
    textures = (*scene.textures, Paint(grass, 0.8), grass)
    return replace(scene, movers=(car,), boxes=static, textures=textures), 1


def _pixel(cam, X) -> tuple[tuple[int, int], float]:
    uv, z = cam.project(np.asarray(X, float))
    return (int(np.rint(uv[1])), int(np.rint(uv[0]))), float(z)


def test_a_mover_is_where_it_was_put_in_each_view_and_gone_where_absent() -> None:
    poses = {"left": (-3.0, 2.0, CAR_Z, 0.0), "right": (5.0, -3.0, CAR_Z, 0.0)}
    scene, tex = _scene_with_car(poses)
    left, right, back = (render_layers(scene, v) for v in ("left", "right", "back"))
    front_left = (-3.0, 2.0 - 0.75, CAR_Z - 0.9)  # middle of its front face in the left view
    (v, u), z = _pixel(scene.cameras["left"], front_left)
    assert left.surface[v, u] == tex
    assert left.depth[v, u] == pytest.approx(z, abs=1e-4)
    # The right camera looks at that spot and sees the terrain behind: the car has gone ...
    (v, u), z = _pixel(scene.cameras["right"], front_left)
    assert right.surface[v, u] == 0 and right.depth[v, u] > z + 3
    # ... to where it was put for the right view.
    (v, u), z = _pixel(scene.cameras["right"], (5.0, -3.0 - 0.75, CAR_Z - 0.9))
    assert right.surface[v, u] == tex and right.depth[v, u] == pytest.approx(z, abs=1e-4)
    assert not np.any(back.surface == tex)
    # About 4.5 m x 1.5 m at 290 m: f = 3053 px at 320 px wide.
    f = scene.cameras["left"].f
    assert np.count_nonzero(left.surface == tex) == pytest.approx(
        4.5 * 1.5 * (f / (CAR_Z - 0.9)) ** 2, rel=0.1)


def test_moved_mask_is_the_mover_in_left_plus_what_it_hides_elsewhere() -> None:
    # The car at a different place in each view, and a static box half-way that hides
    # part of it from the right camera: what it hides there was not changed by the car.
    poses = {"left": (-3.0, 2.0, CAR_Z, 0.0), "right": (5.0, -3.0, CAR_Z, 10.0),
             "back": (-6.0, -6.0, CAR_Z, -5.0)}
    blocker = Box((4.1, -1.95, 150.0), (0.6, 0.6, 0.3), (0.0, 0.0, 0.0), 2)
    scene, tex = _scene_with_car(poses, (blocker,))
    layers = {v: render_layers(scene, v) for v in ("left", "right", "back")}
    left = layers["left"]
    mask = moved_left(scene, left.surface, left.depth)
    # Independently: lift each left pixel, look up what the other views' renders show at
    # its projection (nearest pixel), and call it moved where that is the car.
    cam = scene.cameras["left"]
    v, u = np.mgrid[0 : cam.height, 0 : cam.width].astype(float)
    X = cam.C + cam.rays(u, v) * left.depth[..., None]
    in_left = left.surface == tex
    expected = in_left.copy()
    for view in ("right", "back"):
        other = scene.cameras[view]
        uv, _ = other.project(X)
        ui, vi = np.rint(uv[..., 0]).astype(int), np.rint(uv[..., 1]).astype(int)
        inside = (ui >= 0) & (ui < other.width) & (vi >= 0) & (vi < other.height)
        seen = np.full(mask.shape, -1)
        seen[inside] = layers[view].surface[vi[inside], ui[inside]]
        hidden = seen == tex
        assert np.count_nonzero(hidden & ~in_left) > 300, view  # each view adds its part
        expected |= hidden
    assert mask[in_left].all()
    # They agree but within a pixel of the outline (nearest-pixel lookup there).
    k = np.ones((3, 3), np.uint8)
    e8 = expected.astype(np.uint8)
    edge = cv2.dilate(e8, k).astype(bool) & ~cv2.erode(e8, k).astype(bool)
    assert not np.any((mask ^ expected) & ~edge)
    # Left pixels whose point the right camera would see the car in front of, but for
    # the blocker: not moved.
    right = scene.cameras["right"]
    d = X - right.C
    behind = (box_hits(scene.movers[0].boxes("right")[0], right.C, d)[0] < 1)
    behind &= box_hits(blocker, right.C, d)[0] < 1
    behind &= left.surface == 0
    assert np.count_nonzero(behind) > 100 and not np.any(mask & behind & ~edge)


def test_generated_movers_have_sizes_and_presence_as_documented() -> None:
    scene = generate_scene(replace(BARE, n_movers=40, sky=0.3), 8)
    kinds = {m.kind for m in scene.movers}
    assert kinds == {"car", "person"} and len(scene.movers) == 40
    counts = [len(m.poses) for m in scene.movers]
    assert min(counts) >= 1 and {1, 2, 3} <= set(counts)  # some in one or two views only
    for m in scene.movers:
        length, height, width = m.size()
        if m.kind == "car":
            assert 3.8 <= length <= 4.9 and 1.25 <= height <= 1.6 and 1.7 <= width <= 1.9
        else:
            assert 0.4 <= length <= 0.55 and 1.55 <= height <= 1.95
        for x, y, z, _ in m.poses.values():
            # below the skyline, in front of the terrain
            assert y - height > float(scene.terrain.skyline_y(np.array(x)))
            assert z < float(scene.terrain.z(np.array(x), np.array(y))) - 0.5


def test_movers_do_not_change_the_rest_of_the_scene() -> None:
    plain = generate_scene(BARE, 5)
    busy = generate_scene(replace(BARE, n_movers=3, n_shadows=2, n_facades=2), 5)
    assert busy.terrain == plain.terrain and busy.cameras.keys() == plain.cameras.keys()
    assert busy.boxes[: len(plain.boxes)] == plain.boxes
    assert busy.textures[: len(plain.textures)] == plain.textures
    for name, cam in plain.cameras.items():
        assert np.array_equal(cam.R, busy.cameras[name].R) and cam.C.tolist() == busy.cameras[
            name].C.tolist()
