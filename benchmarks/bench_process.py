"""Batch processing at full resolution: time, peak memory per worker and the laser
comparisons' accuracy over synthetic sessions.

    python -m benchmarks.bench_process --seeds 101-104 --work out/eval20
    python -m benchmarks.bench_process --seeds 1-2 --width 1152 --height 864 --work out/small

Scenes are taken from WORK/scenes/seed-N (as benchmarks/eval_synthetic.py renders them)
or rendered when missing, copied to WORK/sessions/seed-N and given laser targets. With
--raw the frames are stored as DNG files (needs the test extras: tifffile), so the RAW
decode is part of the measurement.
"""

from __future__ import annotations

import argparse
import resource
import shutil
import sys
import time
from pathlib import Path

import cv2
import numpy as np
import yaml

from benchmarks.common import OUT, seed_list
from rigkit.batch import auto_jobs, run_batch
from rigkit.batch.pool import BASE_BYTES, BYTES_PER_PIXEL
from rigkit.capture import is_session, load_session
from rigkit.capture.comparisons import LOG_NAME, latest_run, read_rows
from rigkit.reporting.summary import format_text, summarize
from rigkit.synth import SynthParams, generate_scene, write_scene
from rigkit.synth.session import session_from_rendered


def prepare(seed: int, params: SynthParams, work: Path, targets: int, raw: bool) -> Path:
    scene_dir = work / "scenes" / f"seed-{seed}"
    session_dir = work / ("sessions-raw" if raw else "sessions") / f"seed-{seed}"
    if is_session(session_dir):
        return session_dir
    scene = generate_scene(params, seed)
    if not (scene_dir / "scene.yaml").is_file():
        print(f"rendering seed {seed} ...", file=sys.stderr)
        write_scene(scene, scene_dir)
    shutil.rmtree(session_dir, ignore_errors=True)
    shutil.copytree(scene_dir, session_dir)
    if raw:
        to_dng_frames(session_dir)
    session_from_rendered(scene, session_dir, n_targets=targets, seed=seed,
                          frame_suffix=".dng" if raw else ".png")
    return session_dir


def to_dng_frames(folder: Path) -> None:
    """Replace the rendered PNGs by 12-bit DNG mosaics of the same (linearised) light."""
    from tests.dngutil import write_dng  # the tests' DNG writer (no rawpy needed)

    for view in ("left", "right", "back"):
        image = cv2.imread(str(folder / f"{view}.png"), cv2.IMREAD_GRAYSCALE)
        if image is None:
            raise SystemExit(f"{folder / view}.png: cannot read it")
        grey = image / 255.0
        linear = np.where(grey <= 0.04045, grey / 12.92, ((grey + 0.055) / 1.055) ** 2.4)
        write_dng(folder / f"{view}.dng", np.rint(0.6 * 4095 * linear).astype(np.uint16),
                  white_level=4095)
        (folder / f"{view}.png").unlink()


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    ap.add_argument("--seeds", default="101-104")
    ap.add_argument("--width", type=int, default=4608)
    ap.add_argument("--height", type=int, default=3456)
    ap.add_argument("--targets", type=int, default=8)
    ap.add_argument("--jobs", type=int, help="default: as rigkit process chooses")
    ap.add_argument("--raw", action="store_true", help="store the frames as DNG")
    ap.add_argument("--work", type=Path, default=OUT / "eval")
    args = ap.parse_args(argv)
    params = SynthParams(width=args.width, height=args.height)
    sessions = [prepare(s, params, args.work, args.targets, args.raw)
                for s in seed_list(args.seeds)]
    jobs = args.jobs or auto_jobs(sessions)
    t0 = time.perf_counter()
    outcomes = run_batch(sessions, jobs)
    wall = time.perf_counter() - t0
    usage = resource.getrusage(resource.RUSAGE_CHILDREN if jobs > 1 else resource.RUSAGE_SELF)
    rows = [r for s in sessions for r in latest_run(read_rows(s / LOG_NAME))]
    pixels = args.width * args.height
    print(format_text(rows, summarize(rows)))
    print()
    print(f"{len(sessions)} sessions of {args.width}x{args.height} "
          f"({'DNG' if args.raw else 'PNG'} frames), {jobs} at a time: {wall:.1f} s "
          f"({wall / len(sessions):.1f} s per session), "
          f"{sum(o.ok for o in outcomes)} ok")
    peak = usage.ru_maxrss * 1024
    print(f"peak memory of one worker: {peak / 2**30:.2f} GiB = "
          f"{(peak - BASE_BYTES) / pixels:.0f} B/px over the {BASE_BYTES / 2**20:.0f} MiB base "
          f"(auto_jobs assumes {BYTES_PER_PIXEL} B/px)")
    for s in sessions:
        meta = yaml.safe_load((s / "results" / "depth.json").read_text())
        print(f"  {load_session(s).name}: density {100 * meta['density']:.1f} %, offset "
              f"{meta['disparity_offset_px']:.2f} +- {meta['disparity_offset_sigma_px']:.2f} px")
    return 0 if all(o.ok for o in outcomes) else 1


if __name__ == "__main__":
    sys.exit(main())
