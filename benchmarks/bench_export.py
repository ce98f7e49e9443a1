"""rigkit export at full resolution: time and peak memory for a 4608 x 3456 depth map.

    python -m benchmarks.bench_export --work out/bench-export
    python -m benchmarks.bench_export --work out/bench-export --frame camera --format ply
    python -m benchmarks.bench_export --work out/bench-export --format las,dsm --crs EPSG:2056

Builds (once) a session on rigs/p1000-tripod.yaml whose results are a synthetic depth
map (a slanted hillside at 250-350 m with 20 % of the pixels, the sky, without depth),
a tripod position and three targets with laser azimuths and inclinations, then exports
it and prints the points, the time (wall and CPU: the machine may be shared) and the
process's peak resident memory (which includes the memory-mapped depth and sigma maps it
has read).
"""

from __future__ import annotations

import argparse
import math
import resource
import shutil
import sys
import time
from pathlib import Path

import cv2
import numpy as np

from benchmarks.common import OUT, RIGS
from rigkit.capture import LaserReading, add_target, create_session, load_session
from rigkit.capture.positioning import set_tripod_position
from rigkit.capture.results import RunFiles, RunRecord
from rigkit.capture.tripod import TripodPosition
from rigkit.export import MapRequest, export_path

RIG = RIGS / "p1000-tripod.yaml"
LOOK_AZIMUTH_DEG = 47.0


def build(path: Path) -> None:
    """The benchmark session: results, tripod, three targets the laser saw exactly."""
    create_session(path, RIG)
    session = load_session(path)
    width, height = session.rig().image_size
    v, u = np.mgrid[0:height, 0:width].astype(np.float32)
    depth = 300.0 + 50.0 * (u / width - 0.5) - 20.0 * (v / height - 0.5)
    depth[v < 0.2 * height] = np.nan
    results = path / "results"
    results.mkdir()
    np.save(results / "depth.npy", depth.astype(np.float32))
    np.save(results / "sigma.npy", (0.005 * depth).astype(np.float32))
    cv2.imwrite(str(results / "grey.png"), ((u + v) % 256).astype(np.uint8))
    camera = session.rig().intrinsics((width, height))
    f, cx, cy = camera.focal_px, camera.cx_px, camera.cy_px
    record = RunRecord(frames={}, rig=session.rig().geometry(),
                       settings=session.rig().pipeline_settings(), rig_name=session.rig().name,
                       image_size_px=(width, height), left_camera_px=(f, cx, cy),
                       lens=session.rig().geometry().distortion, burst_length=1,
                       median_depth_m=300.0, offset_px=0.0, offset_sigma_px=0.0,
                       offset_depth_fraction=None, run_id="bench")
    RunFiles.of_session(path).record.write_text(record.to_json())
    set_tripod_position(path, TripodPosition(46.55, 7.98, 1012.0, "manual", "bench"))
    for name, (pu, pv) in {"A": (300, 3000), "B": (4300, 900), "C": (4400, 3300)}.items():
        x, y, z = (pu - cx) / f, (pv - cy) / f, 1.0  # level camera looking at 47 deg
        along = math.hypot(x, y, z)
        azimuth = (LOOK_AZIMUTH_DEG + math.degrees(math.atan2(x, z))) % 360
        inclination = -math.degrees(math.asin(y / along))
        reading = LaserReading(float(depth[pv, pu]) * along, "bench", "manual", inclination,
                               azimuth_deg=azimuth)
        add_target(load_session(path), name, (pu, pv), readings=[reading])


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--work", type=Path, default=OUT / "bench-export")
    parser.add_argument("--format", default="ply,las,laz,tif")
    parser.add_argument("--frame", default="map", choices=("camera", "map"))
    parser.add_argument("--step", type=int, default=1)
    parser.add_argument("--crs", help="the map's CRS (default: the UTM zone)")
    args = parser.parse_args(argv)
    session = args.work / "session"
    if not (session / "results" / "depth.npy").is_file():
        shutil.rmtree(session, ignore_errors=True)
        args.work.mkdir(parents=True, exist_ok=True)
        build(session)
    out = args.work / "out"
    t0, cpu0 = time.perf_counter(), time.process_time()
    done = export_path(session, out, args.format.split(","), step=args.step, frame=args.frame,
                       request=MapRequest(crs=args.crs))
    seconds, cpu = time.perf_counter() - t0, time.process_time() - cpu0
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    sizes = ", ".join(f"{p.suffix[1:]} {p.stat().st_size / 1e6:.0f} MB" for p in done.files)
    print(f"{done.points} points ({args.frame} frame, step {args.step}) in {seconds:.1f} s "
          f"({cpu:.1f} CPU s), peak RSS {peak:.0f} MB; {sizes}")
    if done.georef is not None:
        fit = done.georef.orientation
        print(f"orientation: residual RMS {fit.rms_residual_deg:.4f} deg, pointing "
              f"{', '.join(f'{a:.3f}' for a in fit.pointing())} deg")
    return 0


if __name__ == "__main__":
    sys.exit(main())
