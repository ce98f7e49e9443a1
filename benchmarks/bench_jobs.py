"""Several sessions at once: `rigkit process` with a local worker pool and on a local
Dask cluster, whole commands, several runs each (issue 34: N workers must use N cores,
not N x cores).

    python -m benchmarks.bench_jobs --runs 3 --work out/bench-jobs

Copies the bundled example session (1536x1152 px, bursts of 5) --sessions times into
WORK, then times, in turn and --runs times each: `rigkit process --jobs 1`, `--jobs 2`,
and `--scheduler` on a local cluster of 2 worker processes of one thread each (Dask's
own default layout on a 2-core machine). Prints min / median / max wall seconds per way,
the pairwise ratio of the pool's `--jobs 2` to the cluster, and whether every way gave
the same depth maps, bit for bit.
"""

from __future__ import annotations

import argparse
import contextlib
import hashlib
import shutil
import statistics
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path

from benchmarks.common import OUT, ROOT

EXAMPLE = ROOT / "capture" / "example"
RIGKIT = [sys.executable, "-m", "rigkit"]


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--work", type=Path, default=OUT / "bench-jobs")
    parser.add_argument("--sessions", type=int, default=3)
    parser.add_argument("--runs", type=int, default=3)
    args = parser.parse_args(argv)
    sessions = _copies(args.work, args.sessions)
    with _local_cluster() as address:
        ways = {
            "--jobs 1": ["--jobs", "1"],
            "--jobs 2": ["--jobs", "2"],
            "dask, 2 workers": ["--scheduler", address],
        }
        times: dict[str, list[float]] = {name: [] for name in ways}
        depths: dict[str, set[str]] = {name: set() for name in ways}
        for run in range(args.runs):
            for name, flags in ways.items():
                seconds = _process(sessions, flags)
                times[name].append(seconds)
                depths[name].add(_depth_digest(sessions))
                print(f"run {run + 1}/{args.runs}  {name:<16} {seconds:6.1f} s", flush=True)
    print(f"\n{len(sessions)} sessions of {EXAMPLE.name}, {args.runs} runs each")
    print(f"{'way':<16} {'min':>7} {'median':>7} {'max':>7}   (wall s, whole command)")
    for name, values in times.items():
        print(f"{name:<16} {min(values):7.1f} {statistics.median(values):7.1f} "
              f"{max(values):7.1f}")
    ratios = [a / b for a, b in zip(times["--jobs 2"], times["dask, 2 workers"], strict=True)]
    print(f"--jobs 2 / dask: median {statistics.median(ratios):.2f} "
          f"(min {min(ratios):.2f}, max {max(ratios):.2f})")
    digests = set().union(*depths.values())
    print(f"depth maps: {'identical' if len(digests) == 1 else 'DIFFERENT'} across "
          f"{sum(len(v) for v in times.values())} runs")
    return 0


def _copies(work: Path, n: int) -> list[Path]:
    out = []
    for i in range(n):
        target = work / f"example-{i + 1}"
        if not target.exists():
            shutil.copytree(EXAMPLE, target, ignore=shutil.ignore_patterns(
                "results", "derived", "comparisons.csv", "history.log", ".*"))
        out.append(target)
    return out


def _process(sessions: list[Path], flags: list[str]) -> float:
    t0 = time.perf_counter()
    subprocess.run([*RIGKIT, "process", *map(str, sessions), *flags, "--quiet"],
                   check=True, stdout=subprocess.DEVNULL)
    return time.perf_counter() - t0


def _depth_digest(sessions: list[Path]) -> str:
    h = hashlib.sha256()
    for session in sessions:
        h.update((session / "results" / "depth.npy").read_bytes())
    return h.hexdigest()


@contextlib.contextmanager
def _local_cluster() -> Iterator[str]:
    """A local Dask cluster of 2 worker processes, one thread each, for the benchmark's
    duration: its scheduler's address."""
    import distributed

    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                  dashboard_address=None, host="127.0.0.1",
                                  protocol="tcp") as cluster:
        yield str(cluster.scheduler_address)


if __name__ == "__main__":
    sys.exit(main())
