"""What hostile inputs cost (issue 46): ``rigkit session show`` of a session whose
``comparisons.csv`` is a 3 GB (sparse) file, timed from outside with its peak memory,
and the field TUI's walk of a card folder of N frame files, in CPU milliseconds a walk.

    .venv/bin/python -m benchmarks.bench_hostile [--tree PATH] [--files 2000]

``--tree`` runs the first figure with the rigkit of another checkout (its ``rigkit/`` on
PYTHONPATH), e.g. an older commit unpacked with ``git archive``, for the figure before.
"""

from __future__ import annotations

import argparse
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path


def _session(folder: Path) -> Path:
    from rigkit.synth import SynthParams, generate_scene
    from rigkit.synth.session import write_synthetic_session

    session = folder / "s"
    write_synthetic_session(generate_scene(SynthParams(width=160, height=120), 1), session,
                            n_targets=2)
    with (session / "comparisons.csv").open("wb") as log:
        log.truncate(3 << 30)
    return session


def show_large_log(tree: Path | None) -> str:
    """``session show`` on the 3 GB log: wall and CPU seconds, peak memory, exit status."""
    with tempfile.TemporaryDirectory() as tmp:
        session = _session(Path(tmp))
        env = dict(os.environ)
        if tree is not None:
            env["PYTHONPATH"] = str(tree)
        code = ("import sys; from rigkit.cli import main; "
                f"sys.exit(main(['session', 'show', {str(session)!r}]))")
        before = resource.getrusage(resource.RUSAGE_CHILDREN)
        start = time.perf_counter()
        done = subprocess.run([sys.executable, "-c", code], capture_output=True, env=env,
                              cwd=tmp)
        wall = time.perf_counter() - start
        after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return (f"session show, 3 GB comparisons.csv: {wall:.2f} s, CPU {cpu:.2f} s, peak "
            f"{after.ru_maxrss / 1024:.0f} MB, exit {done.returncode}")


def card_walk(files: int) -> str:
    """CPU milliseconds of one walk of a card folder holding ``files`` frame files."""
    from rigkit.tui.watch import frame_files

    with tempfile.TemporaryDirectory() as tmp:
        card = Path(tmp) / "DCIM" / "100NIKON"
        card.mkdir(parents=True)
        for i in range(files):
            (card / f"DSCN{i:04d}.NRW").touch()
        walks = 50
        start = time.process_time()
        for _ in range(walks):
            frame_files(Path(tmp), lambda line: None)
        cpu = (time.process_time() - start) / walks
    return f"card walk, {files} frame files: {1000 * cpu:.1f} ms CPU a walk"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--tree", type=Path, help="another checkout's root, for the figure "
                        "before")
    parser.add_argument("--files", type=int, default=2000,
                        help="frame files on the card walked (default 2000)")
    args = parser.parse_args(argv)
    print(show_large_log(args.tree))
    print(card_walk(args.files))
    return 0


if __name__ == "__main__":
    sys.exit(main())
