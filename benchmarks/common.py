"""What the benchmark scripts share: the checkout's folders (every default path is
relative to the checkout, not to the folder a script is started from), the seed lists
they take, and how a script starts a fresh process of itself."""

from __future__ import annotations

import shutil
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
"""The checkout."""
RIGS = ROOT / "rigs"
"""The bundled rig profiles."""
OUT = ROOT / "out"
"""Where the scripts keep rendered scenes and results by default (not in git)."""
EXAMPLE = ROOT / "capture" / "example"
"""The bundled example session (never processed in place)."""
SHARED_DATA = ROOT.parent / "shared" / "data"
"""Data kept beside the checkout (real camera files, the authors' elephant scene)."""


def seed_list(text: str) -> list[int]:
    """``101-120``, ``7`` or ranges joined by commas (``601-603,605-621``)."""
    seeds: list[int] = []
    for part in text.split(","):
        lo, _, hi = part.partition("-")
        seeds += range(int(lo), int(hi or lo) + 1)
    return seeds


def run_script(name: str, *args: str) -> str:
    """The standard output of ``python -m benchmarks.NAME ARGS`` in a fresh process
    started from the checkout (its stderr passes through); CalledProcessError if it
    fails."""
    done = subprocess.run([sys.executable, "-m", f"benchmarks.{name}", *args], cwd=ROOT,
                          stdout=subprocess.PIPE, text=True, check=True)
    return done.stdout


def processed_example(work: Path) -> Path:
    """A copy of the bundled example under ``work``, processed once (its run id fixed,
    so the copy's results are the same each time); kept and reused while its depth map
    is there."""
    from rigkit.batch import process_session

    session = work / "example"
    if not (session / "results" / "depth.npy").is_file():
        shutil.rmtree(session, ignore_errors=True)
        shutil.copytree(EXAMPLE, session)
        process_session(session, "20260101T000000Z-0051")
    return session
