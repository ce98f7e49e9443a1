"""Time of the field TUI's on-site check of a frame, as the operator waits for it: the
checks (:func:`rigkit.capture.field.onsite_checks`) and the check image shown beside
them (:func:`rigkit.capture.views.check_image`), what ``rigkit field`` runs after each
frame (``FieldApp.check_position``).

    python -m benchmarks.bench_check [SESSION] [--work out/bench] [--runs 5] [--alone]
                                     [--burst SCENE]

SESSION: a capture session with a left, a right and a back frame; by default a
full-resolution (4608x3456) field scene rendered once into ``--work`` (``rigkit synth
--session --field --seed 410``). Each run is a fresh process that checks the left, the
right and the back frame in turn, as they arrive at the tripod; with ``--alone``, each
position is checked in a process of its own, as when ``rigkit field`` is started again
on a session that has the earlier frames (nothing learnt from their checks). Prints
each position's seconds, wall and CPU of the process (threads together), median and
range over the runs, the imports apart, and the verdicts of the last run.

``--burst SCENE``: the left frames of a synthetic burst scene (``rigkit synth --burst N``,
of SESSION's rig) taken one by one into a fresh session with SESSION's rig profile, as
``rigkit field`` takes a frame (``FieldApp``: is the position's newest frame a retake,
does the new one belong to the burst, the frame copied in; then its check): each
frame's arrival and check timed apart.
"""

from __future__ import annotations

import argparse
import json
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from benchmarks.common import OUT, run_script

POSITIONS = ("left", "right", "back")


def check_in_turn(session_path: Path, positions: list[str]) -> dict:
    """Seconds (wall, CPU) of the imports and of each position's check, in turn, in this
    process, and each check's verdicts."""
    wall, cpu = time.perf_counter(), time.process_time()
    from rigkit.capture.field import frames_at, onsite_checks
    from rigkit.capture.session import load_session
    from rigkit.capture.views import check_image

    out: dict = {"import": (time.perf_counter() - wall, time.process_time() - cpu)}
    session = load_session(session_path)
    for position in positions:
        wall, cpu = time.perf_counter(), time.process_time()
        checks = onsite_checks(session, position)
        check_image(session, frames_at(session, position)[-1])
        out[position] = (time.perf_counter() - wall, time.process_time() - cpu)
        out[f"{position} verdicts"] = [f"{c.code} {'ok' if c.ok else 'FAIL'}: {c.message}"
                                       for c in checks]
    return out


def burst_in_turn(rig: Path, scene: Path) -> dict:
    """Seconds (wall, CPU) of each left frame of ``scene`` arriving (``frame N in``) and
    being checked (``frame N``) in a fresh session of the profile ``rig``, and the
    checks' verdicts."""
    wall, cpu = time.perf_counter(), time.process_time()
    from rigkit.capture.actions import create_session
    from rigkit.capture.field import frames_at, ingest, newest_failed, onsite_checks
    from rigkit.capture.views import check_image
    from rigkit.synth import load_scene

    out: dict = {"import": (time.perf_counter() - wall, time.process_time() - cpu)}
    with tempfile.TemporaryDirectory() as folder:
        session = create_session(Path(folder) / "burst", rig)
        for number, path in enumerate(load_scene(scene).frame_paths("left"), 1):
            wall, cpu = time.perf_counter(), time.process_time()
            retake = newest_failed(session, "left")  # as the field TUI ingests a frame
            done = ingest(session, "left", path, replace_existing=retake, burst=not retake,
                          check_burst=not retake)
            if done.held is not None:
                raise SystemExit(f"{path}: held as not of the burst")
            session = done.session
            out[f"frame {number} in"] = (time.perf_counter() - wall, time.process_time() - cpu)
            wall, cpu = time.perf_counter(), time.process_time()
            checks = onsite_checks(session, "left")
            check_image(session, frames_at(session, "left")[-1])
            out[f"frame {number}"] = (time.perf_counter() - wall, time.process_time() - cpu)
            out[f"frame {number} verdicts"] = [f"{c.code} {'ok' if c.ok else 'FAIL'}: "
                                               f"{c.message}" for c in checks]
    return out


def run(session: Path, positions: list[str], burst: Path | None = None) -> dict:
    """:func:`check_in_turn` (or :func:`burst_in_turn`) in a fresh process."""
    what = ["--one-burst", str(burst)] if burst else ["--one", *positions]
    printed = run_script("bench_check", str(session.resolve()), *what)
    return json.loads(printed.strip().splitlines()[-1])


def rendered_session(work: Path) -> Path:
    """The default full-resolution field session, rendered into ``work`` the first time."""
    path = work / "check-4608"
    if not (path / "session.yaml").is_file():
        subprocess.run([sys.executable, "-m", "rigkit", "synth", str(path), "--field", "--seed",
                        "410", "--session", "--quiet"], check=True)
    return path


def spread(values: list[float]) -> str:
    return f"{statistics.median(values):5.2f} ({min(values):.2f}-{max(values):.2f})"


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("session", nargs="?", type=Path)
    ap.add_argument("--work", type=Path, default=OUT / "bench")
    ap.add_argument("--runs", type=int, default=5)
    ap.add_argument("--alone", action="store_true",
                    help="each position in a fresh process of its own")
    ap.add_argument("--burst", type=Path, metavar="SCENE",
                    help="a synthetic burst scene whose left frames arrive one by one")
    ap.add_argument("--one", nargs="+", choices=POSITIONS, help=argparse.SUPPRESS)
    ap.add_argument("--one-burst", type=Path, help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.one:
        print(json.dumps(check_in_turn(args.session, args.one)))
        return 0
    if args.one_burst:
        print(json.dumps(burst_in_turn(args.session / "rig.yaml", args.one_burst)))
        return 0
    session = args.session or rendered_session(args.work)
    groups = [[p] for p in POSITIONS] if args.alone and not args.burst else [list(POSITIONS)]
    runs = [{k: v for group in groups for k, v in run(session, group, args.burst).items()}
            for _ in range(args.runs)]
    how = "each position alone" if args.alone else "in turn"
    print(f"{len(runs)} runs, median (range), s; {'left burst' if args.burst else how}")
    print(f"{'':11} {'wall':>17} {'CPU':>17}")
    timed = [what for what in runs[-1] if not what.endswith("verdicts")]
    for what in timed:
        print(f"{what:11} {spread([r[what][0] for r in runs]):>17} "
              f"{spread([r[what][1] for r in runs]):>17}")
    for what in runs[-1]:
        if what.endswith("verdicts"):
            print(f"{what.removesuffix(' verdicts')}: " + "; ".join(runs[-1][what]))
    return 0


if __name__ == "__main__":
    sys.exit(main())
