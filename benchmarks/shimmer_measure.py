"""Heat shimmer measured from two frames of a burst against what the scene was rendered
with (what `rigkit field` shows from a position's second frame on).

    python -m benchmarks.shimmer_measure out/fieldb5/scenes/seed-2*

For each rendered burst scene (``rigkit synth --burst N`` with shimmer), each position's
frames 1 and 2: the measured RMS per axis and correlation length against the scene's
(px), and the seconds the measurement took.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

from rigkit.core.tables import render_table
from rigkit.errors import RigkitError
from rigkit.imagefile.decode import load_grey
from rigkit.pipeline.shimmer import measure_shimmer
from rigkit.synth import load_scene

VIEWS = ("left", "right", "back")


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("scenes", nargs="+", type=Path)
    args = ap.parse_args(argv)
    rows: list[list[str] | None] = []
    ratios: list[tuple[float, float]] = []
    for scene in args.scenes:
        try:
            truth = load_scene(scene)
            for view in VIEWS:
                paths = truth.frame_paths(view)
                if len(paths) < 2:
                    raise RigkitError(f"{scene}: {view} has a single frame, not a burst")
                t0 = time.perf_counter()
                found = measure_shimmer(load_grey(paths[0]), load_grey(paths[1]), view)
                seconds = time.perf_counter() - t0
                p = truth.params
                ratios.append((found.rms_px / p.shimmer_px, found.corr_px / p.shimmer_corr_px))
                rows.append([scene.name, view, f"{p.shimmer_px:.2f}", f"{found.rms_px:.3f}",
                             f"{p.shimmer_corr_px:.1f}", f"{found.corr_px:.1f}",
                             f"{found.tracker_px:.3f}", str(found.points), f"{seconds:.2f}"])
        except RigkitError as exc:
            print(f"{scene.name}: {exc}", file=sys.stderr)
    if not ratios:
        return 1
    header = ("scene", "view", "rms", "measured", "corr", "measured", "tracker", "points", "s")
    print(render_table(header, rows, left=(0, 1)))
    rms, corr = np.array(ratios).T
    print(f"measured / true: RMS {rms.mean():.3f} +- {rms.std(ddof=1):.3f}, "
          f"correlation {np.nanmean(corr):.3f} +- {np.nanstd(corr, ddof=1):.3f} "
          f"({len(ratios)} frame pairs; spread as one standard deviation)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
