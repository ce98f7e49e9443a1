"""How long the command line takes to answer without running anything (issue 38):
`rigkit --help`, a command's `--help` and a mistyped command, each a whole process.

    python -m benchmarks.bench_cli --runs 15
    PYTHONPATH=/path/to/other/checkout python -m benchmarks.bench_cli   # another rigkit

Runs `python -m rigkit ARGS` with this interpreter and environment from a neutral
folder, so that PYTHONPATH, not the current folder, picks the rigkit timed (named in the
first line): once per case to warm the file cache, then --runs rounds that take the
cases in turn. Prints, per case, the median wall time and its spread: min, max and the
interquartile range.
"""

from __future__ import annotations

import argparse
import statistics
import subprocess
import sys
import tempfile
import time

CASES: dict[str, list[str]] = {
    "rigkit --help": ["--help"],
    "rigkit depth --help": ["depth", "--help"],
    "rigkit field --help": ["field", "--help"],
    "rigkit dpeth (a typo)": ["dpeth"],
}
NEUTRAL = tempfile.gettempdir()
"""Where the processes start: `python -m` puts its folder first on sys.path."""


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--runs", type=int, default=15, help="rounds of all cases (default 15)")
    args = parser.parse_args(argv)
    where = subprocess.run([sys.executable, "-c", "import rigkit; print(rigkit.__file__)"],
                           capture_output=True, text=True, check=True, cwd=NEUTRAL).stdout.strip()
    print(f"rigkit from {where}; {args.runs} runs per case, wall seconds per process")
    for case in CASES.values():  # warm-up, not counted
        _time(case)
    times: dict[str, list[float]] = {name: [] for name in CASES}
    for _ in range(args.runs):
        for name, case in CASES.items():
            times[name].append(_time(case))
    print(f"{'case':<24} {'median':>7} {'min':>7} {'max':>7} {'IQR':>7}")
    for name, values in times.items():
        q1, _, q3 = statistics.quantiles(values, n=4) if len(values) > 1 else values * 3
        print(f"{name:<24} {statistics.median(values):7.3f} {min(values):7.3f} "
              f"{max(values):7.3f} {q3 - q1:7.3f}")
    return 0


def _time(case: list[str]) -> float:
    """Wall seconds of one `python -m rigkit CASE`; help exits 0, a typo 2."""
    start = time.perf_counter()
    done = subprocess.run([sys.executable, "-m", "rigkit", *case], capture_output=True,
                          cwd=NEUTRAL)
    seconds = time.perf_counter() - start
    if done.returncode not in (0, 2):
        raise SystemExit(f"rigkit {' '.join(case)}: exit {done.returncode}\n"
                         f"{done.stderr.decode(errors='replace')}")
    return seconds


if __name__ == "__main__":
    sys.exit(main())
