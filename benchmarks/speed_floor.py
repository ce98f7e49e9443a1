"""The least wall time a ``rigkit depth`` run can take on N cores with the method as it
stands (issue 38): the CPU seconds of the OpenCV calls the run makes (decoding the
frames, SIFT, the trackers, semi-global matching, the warps and filters, encoding
grey.png) and of the interpreter's start and imports, counted call by call, and that
sum divided by N. Everything else the run does (NumPy, the fits, Python itself, the
disk) comes on top, so no arrangement of this run's work over N cores can end sooner;
the whole run's CPU seconds divided by N, printed last, is the least with that on top.

    python -m benchmarks.speed_floor LEFT RIGHT BACK --focal-px F --baseline-lr M
        --baseline-lb M [--cores 2] [--out out/floor/depth.npy]

A position given as comma-separated files is a burst (as ``rigkit depth`` takes it).

The run is made once to warm the file cache and once counted, in this process, with
OpenCV's loops, BLAS and rigkit's view threads held to one thread, so that each call's
CPU time is that of the thread that made it (``time.thread_time``), spread to no other:
the same work as on many threads, since the depth is the same bit for bit on any number
of threads (``tests/pipeline/test_determinism.py``). The imports are timed as a fresh
``python -c`` of the libraries a run loads, CPU seconds of the child process.
"""

from __future__ import annotations

import subprocess
import sys
import time
from collections import defaultdict
from collections.abc import Callable
from typing import Any

from benchmarks.common import OUT
from benchmarks.profile_depth import depth_argv, depth_parser

KINDS = {
    "imdecode": "decoding the frames",
    "detectAndCompute": "SIFT (three coarse copies)",
    "goodFeaturesToTrack": "corners to track",
    "calcOpticalFlowPyrLK": "Lucas-Kanade tracking",
    "compute": "semi-global matching (two passes)",
    "imencode": "encoding grey.png",
}
OTHER = "warps, filters and resizing"
IMPORTS = "import numpy, cv2, scipy.optimize"


class _Counted:
    """An OpenCV object (SIFT, SGBM) whose methods add their thread CPU time to
    ``seconds`` and ``calls`` under the method's name."""

    def __init__(self, inner: Any, seconds: dict[str, float], calls: dict[str, int]) -> None:
        self._inner, self._seconds, self._calls = inner, seconds, calls

    def __getattr__(self, name: str) -> Any:
        attr = getattr(self._inner, name)
        return _counting(attr, name, self._seconds, self._calls) if callable(attr) else attr


def _counting(function: Callable[..., Any], name: str, seconds: dict[str, float],
              calls: dict[str, int]) -> Callable[..., Any]:
    def wrapper(*args: Any, **kwargs: Any) -> Any:
        t0 = time.thread_time()
        try:
            out = function(*args, **kwargs)
        finally:
            seconds[name] += time.thread_time() - t0
            calls[name] += 1
        if name.endswith("_create"):
            return _Counted(out, seconds, calls)
        return out

    return wrapper


def count_opencv(cv2: Any) -> tuple[dict[str, float], dict[str, int]]:
    """Wrap every function of the ``cv2`` module (and the methods of the SIFT and SGBM
    objects it creates) so that their thread CPU seconds and calls add up by name."""
    seconds: dict[str, float] = defaultdict(float)
    calls: dict[str, int] = defaultdict(int)
    for name in dir(cv2):
        attr = getattr(cv2, name)
        if type(attr).__name__ == "builtin_function_or_method":
            setattr(cv2, name, _counting(attr, name, seconds, calls))
    return seconds, calls


def import_seconds() -> float:
    """CPU seconds of a fresh interpreter importing the libraries a run loads."""
    import resource

    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    subprocess.run([sys.executable, "-c", "import numpy, cv2, scipy.optimize"], check=True)
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    return (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)


def main(argv: list[str] | None = None) -> int:
    ap = depth_parser(__doc__, OUT / "floor" / "depth.npy")
    ap.add_argument("--cores", type=int, default=2, help="cores the floor is for (default 2)")
    args = ap.parse_args(argv)
    args.out.parent.mkdir(parents=True, exist_ok=True)

    import cv2

    from rigkit.cli import main as rigkit_main
    from rigkit.core.threads import limit_threads

    limit_threads(1)
    argv = depth_argv(args)
    rigkit_main(argv)  # warms the file cache and the imports
    seconds, calls = count_opencv(cv2)
    cpu0, wall0 = time.process_time(), time.perf_counter()
    rigkit_main(argv)
    cpu, wall = time.process_time() - cpu0, time.perf_counter() - wall0

    by_kind: dict[str, list[float]] = defaultdict(lambda: [0.0, 0])
    for name, s in seconds.items():
        kind = KINDS.get(name, OTHER)
        by_kind[kind][0] += s
        by_kind[kind][1] += calls[name]
    by_kind[IMPORTS] = [import_seconds(), 1]
    others = sorted((s, name) for name, s in seconds.items() if name not in KINDS)[::-1]
    named = {OTHER: "; " + ", ".join(f"{name} {s:.2f}" for s, name in others[:5])}
    floor = sum(s for s, _ in by_kind.values())
    print(f"one run on one thread: {wall:.2f} s wall, {cpu:.2f} s CPU (imports not counted)")
    print(f"{'CPU s':>6} {'calls':>6}  what")
    for kind, (s, n) in sorted(by_kind.items(), key=lambda kv: -kv[1][0]):
        print(f"{s:6.2f} {n:6d}  {kind}{named.get(kind, '')}")
    print(f"{floor:6.2f}         these together: the run's compiled floor")
    print(f"{floor / args.cores:6.2f}         the least wall time on {args.cores} cores "
          f"(every call spread perfectly, nothing else done)")
    whole = cpu + by_kind[IMPORTS][0]
    print(f"{whole / args.cores:6.2f}         the least wall time on {args.cores} cores for "
          f"the whole run's CPU ({whole:.2f} s with the imports), spread perfectly")
    return 0


if __name__ == "__main__":
    sys.exit(main())
