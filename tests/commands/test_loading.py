"""How the command line loads: `rigkit --help`, `rigkit COMMAND --help` and a
mistyped command build the parser from the commands' argument modules alone; the code
that runs a command (rigkit.commands.NAME_run, and through it the pipeline, OpenCV,
SciPy, ...) is imported only when that command runs."""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

from rigkit.cli import COMMANDS, _runner, build_parser

ROOT = Path(__file__).resolve().parents[2]

HEAVY = ("numpy", "scipy", "cv2", "rawpy", "textual", "matplotlib", "dask", "distributed",
         "laspy", "pyproj", "skimage", "pycolmap", "serial", "yaml", "rich")
"""Libraries that no help or usage error needs (numpy, pyserial, PyYAML and rich are
light next to the others, but no help needs them either)."""
PARSER_SIDE = ("rigkit.cli", "rigkit.commands", "rigkit.core", "rigkit.errors")
"""Where the rigkit modules that building the parser imports may come from (not from
the library's layers: rigkit.pipeline, rig, capture, ...)."""
HELP_VALUES = ("rigkit.rig.defaults", "rigkit.rangefinder.defaults",
               "rigkit.experiments.defaults", "rigkit.export.defaults",
               "rigkit.pipeline.settings")
"""The one place of each value --help shows that a library layer uses too (a default, a
list of choices), light modules both import; and their packages, whose names load on
first use."""

# In a fresh interpreter: build the parser, then run every help and a few usage errors
# through main(), and say which modules each of them imported first. What any one of
# them would import on its own is imported by it or by one before it, so a module none
# of them may import shows up in this one process if in any of theirs.
PROBE = """
import argparse, contextlib, io, json, sys

loaded = set(sys.modules)
report = {}

def note(case, code, printed):
    global loaded
    report[case] = {"code": code, "printed": printed, "new": sorted(set(sys.modules) - loaded)}
    loaded = set(sys.modules)

from rigkit.cli import build_parser, main

def commands(parser, prefix=()):
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for name, sub in action.choices.items():
                yield (*prefix, name)
                yield from commands(sub, (*prefix, name))

paths = list(commands(build_parser()))
note("build_parser()", None, None)
cases = [["--help"], ["dpeth"], [], ["rig", "chekc"], ["session"]]
cases += [[*path, "--help"] for path in paths]
for argv in cases:
    out = io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(out):
        try:
            code = main(argv)
        except SystemExit as exc:
            code = exc.code
    note(" ".join(["rigkit", *argv]), code, len(out.getvalue()))
print(json.dumps(report))
"""


def _probe() -> dict[str, dict]:
    done = subprocess.run([sys.executable, "-c", PROBE], capture_output=True, text=True,
                          cwd=ROOT, timeout=120)
    assert done.returncode == 0, done.stderr
    report: dict[str, dict] = json.loads(done.stdout)
    return report


def _not_for_help(module: str) -> str | None:
    """What a failure names for ``module`` (its library, or its rigkit package), or None
    where help may import it."""
    top = module.split(".")[0]
    if top in HEAVY:
        return top
    if top != "rigkit" or module == "rigkit":
        return None
    if module.endswith("_run"):
        return module
    packages = {value.rsplit(".", 1)[0] for value in HELP_VALUES}
    if module in HELP_VALUES or module in packages:
        return None
    return None if module.startswith(PARSER_SIDE) else ".".join(module.split(".")[:2])


def test_help_and_usage_errors_import_no_command_code() -> None:
    report = _probe()
    for name in COMMANDS:
        assert f"rigkit {name} --help" in report, name
    assert "rigkit session add-frame --help" in report  # the walk reaches the actions
    offending = {case: sorted({_not_for_help(m) for m in seen["new"]} - {None})
                 for case, seen in report.items()}
    assert {case: names for case, names in offending.items() if names} == {}
    del report["build_parser()"]
    for case, seen in report.items():
        assert seen["printed"] > 0, case
        assert seen["code"] == (0 if case.endswith("--help") else 2), case


def _leaves(parser: argparse.ArgumentParser, prefix: str = "rigkit"
            ) -> Iterator[tuple[str, argparse.ArgumentParser]]:
    subparsers = [a for a in parser._actions if isinstance(a, argparse._SubParsersAction)]
    if not subparsers:
        yield prefix, parser
    for action in subparsers:
        for name, sub in action.choices.items():
            yield from _leaves(sub, f"{prefix} {name}")


def test_every_command_names_a_runner_that_exists() -> None:
    leaves = dict(_leaves(build_parser()))
    assert len(leaves) >= len(COMMANDS)
    for command, parser in leaves.items():
        path = parser.get_default("runner")
        assert isinstance(path, str), command
        assert path.split(":")[0].endswith("_run"), command  # not the arguments' module
        assert callable(_runner(path)), command


def test_what_help_shows_is_what_the_library_uses() -> None:
    """Each value --help shows lives in one place, which the library uses too: no copy
    to keep equal."""
    from rigkit.commands import experiments, rangefinder, rig
    from rigkit.experiments import table1
    from rigkit.rangefinder import driver, protocols, sim
    from rigkit.rig import budget, bursts, profile

    assert rig.DISPARITY_ERROR_PX is budget.DISPARITY_ERROR_PX
    assert rig.MAX_RANGE_M is profile.MAX_RANGE_M
    assert rig.SHIMMER_PX is bursts.SHIMMER_PX
    assert rangefinder.SIM_OPTIONS is sim.SIM_OPTIONS
    assert rangefinder.DEFAULT_TIMEOUT_S is driver.DEFAULT_TIMEOUT_S
    assert [(spec.name, spec.default_baud) for spec in protocols.PROTOCOLS.values()] == \
        list(rangefinder.DEFAULT_BAUDS.items())
    assert experiments.METHODS is table1.METHODS
