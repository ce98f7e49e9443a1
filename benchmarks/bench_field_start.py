"""How long `rigkit field` leaves the terminal blank (issue 49): from starting the
process to its first screen drawn, and to the session's step, in a pseudo-terminal of
80x24, each a whole process.

    .venv/bin/python -m benchmarks.bench_field_start --runs 5
    PYTHONPATH=/path/to/other/checkout:. .venv/bin/python -m benchmarks.bench_field_start

Cases: a new session (it opens at the rig step: "focal length" on screen), and
`--demo` (its first screen, and the rig step once the scene is rendered; with
--no-demo left out). Runs `python -m rigkit field ...` with this interpreter from a
neutral folder, so that PYTHONPATH picks the rigkit timed (named in the first line);
once per case to warm the file cache, then --runs rounds taking the cases in turn, each
ended with q once its step shows. Prints the median wall seconds and the range, and the
machine's load average, since other work on the machine moves these figures.
"""

from __future__ import annotations

import argparse
import fcntl
import os
import select
import shutil
import signal
import statistics
import struct
import subprocess
import sys
import tempfile
import termios
import time
from pathlib import Path

from benchmarks.common import RIGS

RIG = RIGS / "p1000-tripod.yaml"
NEUTRAL = tempfile.gettempdir()
"""Where the processes start: `python -m` puts its folder first on sys.path."""
TITLE = b"rigkit field"
STEP = b"focal length"
TIMEOUT_S = 300.0


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--runs", type=int, default=5, help="rounds of all cases (default 5)")
    parser.add_argument("--no-demo", action="store_true", help="leave the demo out")
    args = parser.parse_args(argv)
    where = subprocess.run([sys.executable, "-c", "import rigkit; print(rigkit.__file__)"],
                           capture_output=True, text=True, check=True, cwd=NEUTRAL).stdout.strip()
    print(f"rigkit from {where}; {args.runs} runs per case, wall seconds per process; "
          f"load average {os.getloadavg()[0]:.1f}")
    with tempfile.TemporaryDirectory() as tmp:
        session = Path(tmp) / "bench"
        subprocess.run([sys.executable, "-m", "rigkit", "session", "new", str(session),
                        "--rig", str(RIG)], check=True, capture_output=True, cwd=NEUTRAL)
        cases = {"rigkit field SESSION": [str(session)]}
        if not args.no_demo:
            cases["rigkit field --demo"] = ["--demo"]
        for case in cases.values():  # warm-up, not counted
            _time(case)
        times: dict[str, list[tuple[float, float]]] = {name: [] for name in cases}
        for _ in range(args.runs):
            for name, case in cases.items():
                times[name].append(_time(case))
    print(f"{'case':<22} {'first screen':>22} {'the step':>22}")
    for name, values in times.items():
        first, step = ([v[i] for v in values] for i in (0, 1))
        print(f"{name:<22} {_spread(first):>22} {_spread(step):>22}")
    print(f"load average at the end {os.getloadavg()[0]:.1f}")
    return 0


def _spread(values: list[float]) -> str:
    return f"{statistics.median(values):.2f} ({min(values):.2f}-{max(values):.2f})"


def _time(case: list[str]) -> tuple[float, float]:
    """(seconds to the first screen, seconds to the step) of one `rigkit field CASE` in
    an 80x24 pseudo-terminal."""
    demos = _demos()
    main_fd, child_fd = os.openpty()
    fcntl.ioctl(child_fd, termios.TIOCSWINSZ, struct.pack("HHHH", 24, 80, 0, 0))
    env = {**os.environ, "TERM": "xterm-256color", "COLUMNS": "80", "LINES": "24"}
    start = time.perf_counter()
    child = subprocess.Popen([sys.executable, "-m", "rigkit", "field", *case], cwd=NEUTRAL,
                             stdin=child_fd, stdout=child_fd, stderr=child_fd, env=env,
                             start_new_session=True)
    os.close(child_fd)
    seen, first, step = b"", None, None
    try:
        while step is None and time.perf_counter() - start < TIMEOUT_S:
            ready, _, _ = select.select([main_fd], [], [], 0.02)
            if ready:
                seen += os.read(main_fd, 1 << 16)
            if first is None and TITLE in seen:
                first = time.perf_counter() - start
            if STEP in seen:
                step = time.perf_counter() - start
        os.write(main_fd, b"q")
        _drain(main_fd, child)
    finally:
        if child.poll() is None:
            os.killpg(child.pid, signal.SIGTERM)
            child.wait()
        os.close(main_fd)
        for folder in _demos() - demos:  # what `rigkit field --demo` keeps, once timed
            shutil.rmtree(folder, ignore_errors=True)
    if first is None or step is None:
        raise SystemExit(f"rigkit field {' '.join(case)}: no screen in {TIMEOUT_S:g} s")
    return first, step


def _drain(fd: int, child: subprocess.Popen[bytes]) -> None:
    """Read what the app writes while it quits (a full pseudo-terminal would block it)."""
    deadline = time.perf_counter() + 30
    while child.poll() is None and time.perf_counter() < deadline:
        ready, _, _ = select.select([fd], [], [], 0.05)
        if ready:
            try:
                os.read(fd, 1 << 16)
            except OSError:
                return


def _demos() -> set[Path]:
    return set(Path(tempfile.gettempdir()).glob("rigkit-demo-*"))


if __name__ == "__main__":
    sys.exit(main())
