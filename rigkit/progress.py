"""Progress lines on stderr for long work (rewritten in place on a terminal)."""

from __future__ import annotations

import sys
import time


class Progress:
    """Report a fraction done per task: ``Progress('render')('left', 0.5)``.

    On a terminal the line is rewritten in place; otherwise one line is printed per
    quarter, so logs stay short. ``quiet`` silences it.
    """

    def __init__(self, label: str, quiet: bool = False) -> None:
        self.label = label
        self.quiet = quiet
        self.tty = sys.stderr.isatty()
        self.t0 = time.perf_counter()
        self._last: dict[str, int] = {}

    def __call__(self, task: str, fraction: float) -> None:
        if self.quiet:
            return
        pct = int(100 * min(max(fraction, 0.0), 1.0))
        elapsed = time.perf_counter() - self.t0
        line = f"{self.label}: {task} {pct:3d}% ({elapsed:.1f} s)"
        if self.tty:
            end = "\n" if pct == 100 else ""
            print(f"\r{line}\033[K", end=end, file=sys.stderr, flush=True)
        elif pct // 25 > self._last.get(task, -1):
            self._last[task] = pct // 25
            print(line, file=sys.stderr, flush=True)
