"""Where the time of one whole ``rigkit depth`` command goes: a table of its stages
(imports, reading the frames, the pipeline's stages as ``depth.json`` records them,
writing the outputs) and, with ``--profile N``, cProfile's N costliest functions by
cumulative and by own time.

    python -m benchmarks.profile_depth LEFT RIGHT BACK --focal-px F --baseline-lr M
        --baseline-lb M [--out out/profile/depth.npy] [--profile 40] [--repeat 3]

A position given as comma-separated files is a burst (as ``rigkit depth`` takes it).
``--repeat`` runs the command that many times in this process (after the first,
imports cost nothing) and prints each run's row: the machine's noise shows in their
spread; ``--memory`` adds each stage's peak resident memory; ``--cpu`` gives each
stage's CPU seconds (the process's, all threads together) instead of its wall seconds,
which a machine shared with other jobs moves far less; ``--busy`` adds, under each run's
wall seconds, how many cores each stage kept busy on average (its CPU seconds over its
wall seconds: 1.0 on 2 cores is one of them idle). Run it against another
checkout with ``PYTHONPATH=/that/checkout`` to compare (docs/results.md).
"""

from __future__ import annotations

import argparse
import cProfile
import io
import json
import os
import pstats
import resource
import sys
import threading
import time
from collections.abc import Callable
from pathlib import Path

from benchmarks.common import OUT

STAGES = ("matching", "lens", "rectification", "stereo", "ambiguity", "agreement", "depth")


def _timed(module: object, name: str, times: dict[str, float], key: str,
           clock: Callable[[], float]) -> None:
    """Wrap ``module.name`` so that the seconds (of ``clock``) its calls take add up in
    ``times[key]`` (and ``times[key + '@']`` holds when the last call started)."""
    inner = getattr(module, name)

    def wrapper(*args: object, **kwargs: object) -> object:
        t0 = clock()
        times[key + "@"] = t0
        try:
            return inner(*args, **kwargs)
        finally:
            times[key] = times.get(key, 0.0) + clock() - t0

    setattr(module, name, wrapper)


def _staged(module: object, stages: dict[str, float], clock: Callable[[], float]) -> None:
    """Wrap ``module.estimate_depth`` so that each stage's seconds of ``clock`` land in
    ``stages`` (its progress calls mark where the stages end)."""
    inner = module.estimate_depth  # type: ignore[attr-defined]

    def wrapper(*args: object, progress: Callable[[str, float], None] | None = None,
                **kwargs: object) -> object:
        last = clock()

        def lap(stage: str, fraction: float) -> None:
            nonlocal last
            now = clock()
            stages[stage], last = now - last, now
            if progress is not None:
                progress(stage, fraction)

        return inner(*args, progress=lap, **kwargs)

    module.estimate_depth = wrapper  # type: ignore[attr-defined]


class RssSampler:
    """Resident memory (MB) every 2 ms in a thread, as (perf_counter, MB) pairs."""

    def __init__(self) -> None:
        self.samples: list[tuple[float, float]] = []
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)
        self._page_mb = os.sysconf("SC_PAGE_SIZE") / 2**20
        self._thread.start()

    def _run(self) -> None:
        with open("/proc/self/statm") as statm:
            while not self._stop.wait(0.002):
                statm.seek(0)
                pages = int(statm.read().split()[1])
                self.samples.append((time.perf_counter(), pages * self._page_mb))

    def stop(self) -> None:
        self._stop.set()
        self._thread.join()

    def peak(self, t0: float, t1: float) -> float:
        return max((mb for t, mb in self.samples if t0 <= t <= t1), default=float("nan"))


def depth_parser(description: str, out: Path) -> argparse.ArgumentParser:
    """The arguments of a ``rigkit depth`` run to measure: the three positions (a
    comma-separated burst each, or one file), the rig's three numbers, and ``--out``
    (default ``out``)."""
    ap = argparse.ArgumentParser(description=description,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    for position in ("left", "right", "back"):
        ap.add_argument(position)
    for flag in ("--focal-px", "--baseline-lr", "--baseline-lb"):
        ap.add_argument(flag, required=True)
    ap.add_argument("--out", type=Path, default=out)
    return ap


def depth_argv(args: argparse.Namespace) -> list[str]:
    """The ``rigkit depth`` command line of :func:`depth_parser`'s ``args``, quiet."""
    return ["depth", args.left, args.right, args.back, "--focal-px", args.focal_px,
            "--baseline-lr", args.baseline_lr, "--baseline-lb", args.baseline_lb,
            "--out", str(args.out), "--quiet"]


def main(argv: list[str] | None = None) -> int:
    ap = depth_parser(__doc__, OUT / "profile" / "depth.npy")
    ap.add_argument("--profile", type=int, default=0, metavar="N",
                    help="print cProfile's N costliest functions (default: no profile)")
    ap.add_argument("--repeat", type=int, default=1)
    ap.add_argument("--memory", action="store_true",
                    help="sample resident memory and print each stage's peak (MB)")
    ap.add_argument("--cpu", action="store_true",
                    help="CPU seconds of the process per stage instead of wall seconds")
    ap.add_argument("--busy", action="store_true",
                    help="under each run's wall seconds, the cores each stage kept busy")
    args = ap.parse_args(argv)
    if args.busy and args.cpu:
        ap.error("--busy goes with wall seconds: leave out --cpu")
    args.out.parent.mkdir(parents=True, exist_ok=True)
    clock = time.process_time if args.cpu else time.perf_counter

    t0 = clock()
    import rigkit.batch.depthrun as depthrun
    import rigkit.core.files as files
    from rigkit.cli import main as rigkit_main

    imports = clock() - t0
    times: dict[str, float] = {}
    cpu_stages: dict[str, float] = {}
    _timed(depthrun, "load_capture", times, "load", clock)
    _timed(files, "write_together", times, "write", clock)
    cpu_times: dict[str, float] = {}
    if args.cpu or args.busy:
        _staged(depthrun, cpu_stages, time.process_time)
    if args.busy:
        _timed(depthrun, "load_capture", cpu_times, "load", time.process_time)
        _timed(files, "write_together", cpu_times, "write", time.process_time)
    argv = depth_argv(args)
    header = (f"{'run':>3} {'import':>6} {'load':>5} "
              + " ".join(f"{s[:6]:>6}" for s in STAGES)
              + f" {'write':>5} {'other':>5} {'total':>6} {'peak MB':>7}")
    print(header)
    profiler = cProfile.Profile() if args.profile else None
    for run in range(args.repeat):
        times.clear()
        cpu_times.clear()
        t1, c1 = clock(), time.process_time()
        sampler = RssSampler() if args.memory else None
        if profiler is not None:
            profiler.enable()
        rigkit_main(argv)
        if profiler is not None:
            profiler.disable()
        if sampler is not None:
            sampler.stop()
        total = clock() - t1 + (imports if run == 0 else 0.0)
        stages = cpu_stages if args.cpu else json.loads(
            args.out.with_suffix(".json").read_text())["timings_s"]
        known = sum(stages.get(s, 0.0) for s in STAGES) + times["load"] + times["write"]
        known += imports if run == 0 else 0.0
        peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
        print(f"{run + 1:>3} {imports if run == 0 else 0.0:6.2f} {times['load']:5.2f} "
              + " ".join(f"{stages.get(s, 0.0):6.2f}" for s in STAGES)
              + f" {times['write']:5.2f} {total - known:5.2f} {total:6.2f} {peak:7.0f}")
        if args.busy:
            cpu_total = time.process_time() - c1
            cpu = [cpu_times["load"], *(cpu_stages.get(s, 0.0) for s in STAGES),
                   cpu_times["write"]]
            wall = [times["load"], *(stages.get(s, 0.0) for s in STAGES), times["write"]]
            print(f"{'':>3} {'cores':>6} " + " ".join(
                f"{c / w if w > 0 else 0.0:{5 if i in (0, len(cpu) - 1) else 6}.2f}"
                for i, (c, w) in enumerate(zip(cpu, wall, strict=True)))
                + f" {'':>5} {cpu_total / (clock() - t1):6.2f}")
        if sampler is not None and not args.cpu:  # the stages follow one another
            edges = [("load", times["load@"], times["load@"] + times["load"])]
            at = edges[0][2]
            for stage in STAGES:
                edges.append((stage, at, at + stages.get(stage, 0.0)))
                at += stages.get(stage, 0.0)
            edges.append(("until write", at, times["write@"]))
            edges.append(("write", times["write@"], times["write@"] + times["write"]))
            print("    peak RSS MB: " + ", ".join(
                f"{name} {sampler.peak(a, b):.0f}" for name, a, b in edges))
    if profiler is not None:
        for order in ("cumulative", "tottime"):
            text = io.StringIO()
            pstats.Stats(profiler, stream=text).sort_stats(order).print_stats(args.profile)
            print(f"\n--- by {order} ---")
            print("\n".join(line[:160] for line in text.getvalue().splitlines()[6:]))
    return 0


if __name__ == "__main__":
    sys.exit(main())
