"""What back-projecting through the run's lens, rather than a pinhole, changes on a
distorting scene: the bundled example (lens k1 0.47, the corner 2.4 px out), processed,
placed on the map from its truth.

    python -m benchmarks.backprojection --work out/bench-backprojection

For every estimated pixel, the point rigkit exports (its depth along the pixel's ray, the
camera oriented by the fit to the targets' laser directions through the same rays) is
compared with the ray-traced point, both in the local east-north-up frame at the tripod:
the distance across the line of sight (the depth's own error lies along it), at the
image centre (within 10 % of the half-diagonal) and the corners (beyond 90 %). Then each
target's estimated range (the laser comparison's) against its true range. Once through
the run's lens (rigkit's), once through a pinhole at the same principal point (as
rigkit back-projected before it used the run's lens).
"""

from __future__ import annotations

import argparse
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np

from benchmarks.common import OUT, processed_example
from rigkit.capture import load_session
from rigkit.export.georef import orient_camera
from rigkit.export.source import DepthMap, open_depth
from rigkit.geometry import NO_DISTORTION
from rigkit.pipeline.lens import Lens
from rigkit.rangefinder.ranging import range_on_ray
from rigkit.synth import load_scene
from rigkit.synth.placement import Placement, sight_errors

PLACED = Placement(46.55123, 7.98456, 1012.0, 47.3, -50.0, 0.0, 49.6)
"""How capture/example was placed (rigkit.synth.placement.place_session)."""


def across_mm(source: DepthMap, truth_enu: np.ndarray, pixels: np.ndarray,
              depth: np.ndarray) -> np.ndarray:
    """Each pixel's exported point's distance from the truth across its line of sight, mm."""
    session = source.session
    assert session is not None
    rotation = orient_camera(session, source).rotation
    points = (source.lens.rays(pixels) * depth[:, None]) @ rotation.T
    line = truth_enu / np.linalg.norm(truth_enu, axis=1, keepdims=True)
    return 1000 * sight_errors(points, truth_enu, line)[1]


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--work", type=Path, default=OUT / "bench-backprojection")
    args = parser.parse_args(argv)
    session_path = processed_example(args.work)
    source = open_depth(session_path)
    lens = source.lens
    pinhole = replace(source, run=replace(source.run, lens=Lens(
        lens.focal_px, lens.size, NO_DISTORTION, lens.shift)))
    truth = load_scene(session_path)
    left = truth.cameras["left"]
    depth = np.asarray(source.depth)
    v, u = np.nonzero(np.isfinite(depth))
    true_z = truth.depth("left")[v, u].astype(np.float64)
    keep = np.isfinite(true_z)
    v, u, true_z = v[keep], u[keep], true_z[keep]
    truth_enu = (left.rays(u.astype(float), v.astype(float)) * true_z[:, None]) @ (
        PLACED.rotation().T)
    pixels = np.column_stack([u, v]).astype(np.float64)
    radius = np.hypot(u - lens.image_centre[0], v - lens.image_centre[1])
    radius /= np.hypot(*lens.image_centre)
    print(f"capture/example: lens k1..k3 {lens.distortion} ({source.run.lens_source}), "
          f"{len(u)} points")
    print("across the line of sight, mm     centre median  p99   corner median  p99")
    for name, model in (("run's lens (rigkit)", source), ("pinhole (before)", pinhole)):
        across = across_mm(model, truth_enu, pixels, depth[v, u].astype(np.float64))
        centre, corner = across[radius < 0.1], across[radius > 0.9]
        print(f"  {name:<28} {np.median(centre):13.1f} {np.percentile(centre, 99):5.1f} "
              f"{np.median(corner):14.1f} {np.percentile(corner, 99):5.1f}")
    print("laser comparison: estimated range minus true range, mm (the depth's own error "
          "included)")
    session = load_session(session_path)
    for target in session.targets:
        pu, pv = target.pixel
        half = target.window_px // 2
        window = depth[round(pv) - half:round(pv) + half + 1, round(pu) - half:round(pu) + half + 1]
        z = float(np.median(window[np.isfinite(window)]))
        true_range = float(target.note.split()[2])
        ranges = [range_on_ray(z, tuple(model.lens.rays(np.array([[pu, pv]]))[0]))
                  for model in (source, pinhole)]
        lens_mm, pinhole_mm = (1000 * (r - true_range) for r in ranges)
        print(f"  {target.name}  pixel ({pu:6.0f}, {pv:6.0f})  lens {lens_mm:+8.1f}  pinhole "
              f"{pinhole_mm:+8.1f}  difference {lens_mm - pinhole_mm:+6.2f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
