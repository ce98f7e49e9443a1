"""The georeferencing's error budget from the laser's direction errors: how far the
orientation fit (rigkit.export.georef.wahba_rotation) moves points at 300 m, by number
of targets, for the P1000 tripod's 4.95 x 3.72 degree view.

    python -m benchmarks.georef_budget
    python -m benchmarks.georef_budget --azimuth-sigma 1 --inclination-sigma 0.25 --trials 2000

Each trial puts n targets at random pixels of the inner 80 % of the image (drawn again
when they span less than rigkit's minimum), adds independent Gaussian errors to each
target's azimuth and inclination, fits the orientation and measures how far the fit
moves the points at 300 m at the image centre and at a corner. A common compass offset
(declination wrong by d) adds d at every point and is not reduced by more targets.
"""

from __future__ import annotations

import argparse
import math
import sys

import numpy as np

from benchmarks.common import RIGS
from rigkit.capture.tripod import enu_direction
from rigkit.export.georef import (
    MIN_SPREAD_DEG,
    MIN_SPREAD_FRACTION,
    wahba_rotation,
)
from rigkit.rig import load_rig

RIG = RIGS / "p1000-tripod.yaml"

RANGE_M = 300.0


def unit(v: np.ndarray) -> np.ndarray:
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def trial(rng: np.random.Generator, n: int, size: tuple[int, int], f: float,
          sigmas: tuple[float, float], min_spread: float) -> tuple[float, float]:
    width, height = size
    while True:
        u = rng.uniform(0.1, 0.9, n) * width
        v = rng.uniform(0.1, 0.9, n) * height
        rays = unit(np.column_stack([(u - width / 2) / f, (v - height / 2) / f, np.ones(n)]))
        spread = max(math.degrees(math.acos(min(1.0, float(a @ b))))
                     for i, a in enumerate(rays) for b in rays[i + 1:])
        if spread >= min_spread:
            break
    # Camera level, looking north: camera (x right, y down, z forward) -> ENU.
    truth = np.array([[1.0, 0, 0], [0, 0, 1.0], [0, -1.0, 0]])
    enu = rays @ truth.T
    azimuth = np.degrees(np.arctan2(enu[:, 0], enu[:, 1])) + rng.normal(0, sigmas[0], n)
    inclination = np.degrees(np.arcsin(enu[:, 2])) + rng.normal(0, sigmas[1], n)
    seen = np.array([enu_direction(a, i) for a, i in zip(azimuth, inclination, strict=True)])
    fitted = wahba_rotation(rays, seen)
    centre = np.array([0.0, 0.0, 1.0])
    corner = unit(np.array([width / 2 / f, height / 2 / f, 1.0]))
    centre_m, corner_m = (RANGE_M * float(np.linalg.norm((fitted - truth) @ p))
                          for p in (centre, corner))
    return centre_m, corner_m


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--azimuth-sigma", type=float, default=1.0, help="deg, per target")
    parser.add_argument("--inclination-sigma", type=float, default=0.25, help="deg")
    parser.add_argument("--trials", type=int, default=2000)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args(argv)
    rig = load_rig(RIG)
    size, f = rig.image_size, rig.focal_px
    fov = 2 * math.degrees(math.atan(math.hypot(*size) / 2 / f))
    min_spread = min(MIN_SPREAD_DEG, MIN_SPREAD_FRACTION * fov)
    rng = np.random.default_rng(args.seed)
    print(f"azimuth sigma {args.azimuth_sigma} deg, inclination sigma "
          f"{args.inclination_sigma} deg, {args.trials} trials, points at {RANGE_M:g} m")
    print("targets  centre RMS m  corner RMS m")
    for n in (2, 3, 4, 6, 10):
        errors = np.array([trial(rng, n, size, f, (args.azimuth_sigma, args.inclination_sigma),
                                 min_spread) for _ in range(args.trials)])
        rms = np.sqrt((errors**2).mean(axis=0))
        print(f"{n:>7}  {rms[0]:12.2f}  {rms[1]:12.2f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
