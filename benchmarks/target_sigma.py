"""How well a laser target's stated sigma matches what its window's median really misses
by, on rendered sessions with ground truth (docs/results-log.md, "A calibration a
surveyor would sign").

    rigkit synth out/ts/s301 --seed 301 --width 1152 --height 864 --session \
        --targets 30 --laser-noise 0.3      # and --field, --width 2304, other seeds
    rigkit process out/ts/s301
    python -m benchmarks.target_sigma out/ts/*

For each processed session: each target's estimate against its true range (the synthetic
writer notes it), less the session's median miss (the run's offset, common to its
targets); their robust RMS (1.4826 MAD, the laser's noise in it); the own part of the
pipeline's per-pixel sigma at the window's median (the offset's share taken out), and the
measured sigma of the window's median (:func:`rigkit.batch.compare.median_scatter`); and
the misses in units of the measured sigma with the laser's (robust RMS: 1 is honest).
"""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

import numpy as np

from rigkit.batch.compare import median_scatter
from rigkit.capture import load_session
from rigkit.capture.comparisons import LOG_NAME, latest_run, read_rows
from rigkit.capture.results import RunFiles, read_record


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("sessions", nargs="+", type=Path)
    parser.add_argument("--laser-sigma-m", type=float, default=0.3,
                        help="the readings' simulated noise, m")
    args = parser.parse_args(argv)
    print(f"{'session':>10} {'targets':>7} {'miss RMS':>9} {'per-pixel':>9} "
          f"{'measured':>9} {'z RMS':>6} {'|z|>3.29':>8}")
    every = []
    for path in args.sessions:
        z = _session(path, args.laser_sigma_m)
        every += list(z)
    every_z = np.array(every)
    print(f"all: {len(every_z)} targets, z robust RMS {_robust(every_z):.2f}, "
          f"|z| > 3.29 in {np.mean(np.abs(every_z) > 3.29):.1%}")
    return 0


def _robust(values: np.ndarray) -> float:
    return float(1.4826 * np.median(np.abs(values - np.median(values))))


def _session(path: Path, laser_m: float) -> np.ndarray:
    session = load_session(path)
    depth = np.load(path / "results" / "depth.npy")
    sigma = np.load(path / "results" / "sigma.npy")
    record = read_record(RunFiles.of_session(path).record)
    offset = record.offset_depth_fraction or 0.0
    median_depth = record.median_depth_m or math.nan
    rows = {r.target: r for r in latest_run(read_rows(path / LOG_NAME))}
    misses, pixel, measured = [], [], []
    for target in session.targets:
        row = rows.get(target.name)
        if row is None or not row.ok:
            continue
        true = float(target.note.split()[2])
        u, v, half = round(target.pixel[0]), round(target.pixel[1]), target.window_px // 2
        window = depth[v - half:v + half + 1, u - half:u + half + 1]
        z = float(np.nanmedian(window))
        per_pixel = float(np.nanmedian(sigma[v - half:v + half + 1, u - half:u + half + 1]))
        share = offset * z / median_depth
        pixel.append(math.sqrt(max((per_pixel / z) ** 2 - share**2, 0.0)))
        measured.append(median_scatter(depth, target.pixel[0], target.pixel[1],
                                       target.window_px))
        misses.append((row.estimate_range_m - true) / true)
    miss = np.array(misses) - np.median(misses)
    stated = np.hypot(np.array(measured), laser_m / np.array([300.0] * len(measured)))
    z = miss / stated
    print(f"{path.name:>10} {len(miss):>7} {100 * _robust(miss):8.3f}% "
          f"{100 * np.median(pixel):8.3f}% {100 * np.nanmedian(measured):8.3f}% "
          f"{_robust(z):6.2f} {int(np.sum(np.abs(z) > 3.29)):>8}")
    return z


if __name__ == "__main__":
    sys.exit(main())
