"""Every benchmark script (the figures in docs/results.md and the README come from them)
imports, answers --help, and, where it has a size small enough, runs: a script that
rots (an import of a function removed, a renamed option) fails here, not in front of
someone reproducing a figure."""

from __future__ import annotations

import importlib
import subprocess
import sys
from pathlib import Path

import pytest

from benchmarks.common import ROOT

SCRIPTS = sorted(p.stem for p in (ROOT / "benchmarks").glob("*.py")
                 if p.stem not in ("__init__", "common"))

TINY = {
    "georef_budget": ["--trials", "5"],
    "bench_cli": ["--runs", "1"],
    "bench_field_start": ["--runs", "1", "--no-demo"],
    "bench_hostile": ["--files", "20"],
    "bench_export": ["--step", "64", "--format", "ply", "--work", "{tmp}"],
    "eval_synthetic": ["--seeds", "1", "--width", "384", "--height", "288", "--work", "{tmp}"],
}
"""Each script's smallest run (``{tmp}``: a folder of the test's own)."""
NO_TINY_RUN = {
    "backprojection": "processes the bundled example",
    "baseline_diagnostics": "needs Table 1 scenes with poses (rigkit experiments table1)",
    "bench_calibrate": "renders, processes and calibrates whole sessions",
    "bench_check": "times the field checks in fresh processes, several runs",
    "bench_depth": "renders and runs the pipeline in a fresh process per size",
    "bench_jobs": "processes copies of the bundled example on a pool and a Dask cluster",
    "bench_process": "renders and processes sessions in a worker pool",
    "eval_elephant": "needs the authors' elephant scene beside the checkout",
    "export_truth": "processes the bundled example and exports it twice",
    "offset_bound": "needs rendered field scenes (rigkit synth --field)",
    "offset_sources": "needs rendered field scenes (rigkit synth --field)",
    "profile_depth": "times a whole rigkit depth on given frames",
    "shimmer_measure": "needs rendered burst scenes with shimmer",
    "speed_floor": "counts a whole rigkit depth call by call",
    "target_sigma": "needs processed rendered sessions with laser targets",
}
"""Why a script has no run here (its --help is still checked)."""


def test_every_script_is_listed_once() -> None:
    """A new script gets a tiny run or a reason, and a line in benchmarks/README.md."""
    assert sorted([*TINY, *NO_TINY_RUN]) == SCRIPTS
    index = (ROOT / "benchmarks" / "README.md").read_text()
    assert [name for name in SCRIPTS if f"`{name}.py`" not in index] == []


@pytest.mark.parametrize("name", SCRIPTS)
def test_the_script_imports_and_answers_help(name: str,
                                             capsys: pytest.CaptureFixture[str]) -> None:
    module = importlib.import_module(f"benchmarks.{name}")
    with pytest.raises(SystemExit) as done:
        module.main(["--help"])
    assert done.value.code == 0
    assert "usage:" in capsys.readouterr().out


@pytest.mark.slow
@pytest.mark.parametrize("name", sorted(TINY))
def test_the_scripts_smallest_run(name: str, tmp_path: Path) -> None:
    """A fresh process, as the README runs it: ``python -m benchmarks.NAME``."""
    argv = [a.replace("{tmp}", str(tmp_path / "work")) for a in TINY[name]]
    done = subprocess.run([sys.executable, "-m", f"benchmarks.{name}", *argv], cwd=ROOT,
                          capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr[-2000:]
    assert done.stdout.strip(), done.stderr[-2000:]
