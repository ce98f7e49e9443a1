"""Every command the README and the docs show runs as written after the README's set-up:
rigkit's commands parse with rigkit's own parser (a synopsis such as ``rigkit depth
LEFT RIGHT BACK [--preview]`` names a command and options that exist), the cheap ones
run, benchmark scripts are started as modules with the checkout's interpreter and take
the options shown, and scripts exist. docs/results-log.md, a dated history, is left as
it was written."""

from __future__ import annotations

import argparse
import contextlib
import io
import re
import shlex
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import pytest

from rigkit.cli import build_parser, main

ROOT = Path(__file__).resolve().parents[2]
DOCS = [ROOT / "README.md", ROOT / "benchmarks" / "README.md",
        *sorted(p for p in (ROOT / "docs").glob("*.md") if p.name != "results-log.md")]
STARTS = ("rigkit ", ".venv/bin/rigkit ", "python ", "python3 ", ".venv/bin/python ",
          "bash scripts/", "PYTHONPATH=")
SYNOPSIS = re.compile(r"\[|\]|\.\.\.|…|\||<|\b[A-Z][A-Z0-9_]*\b(?![.:/=])")
"""What marks a synopsis rather than a command to run: optional parts, repetition,
alternatives, placeholders in capitals (LEFT, SESSION, DIR)."""


def commands(path: Path) -> Iterator[tuple[int, str, bool]]:
    """(line number, command, whole) for every command the file shows: in code blocks
    (``whole``: to run as written), the lines of a bash block, a console block's lines
    after ``$``, and in other blocks the lines that are commands (not a program's output,
    ``rigkit rig: error: ...``, nor a diagram's arrows), continuation lines joined and
    comments and a trailing ``&`` cut; and inline code spans (a command named in a
    sentence or a table: its command and options must exist)."""
    fence, pending, start = None, "", 0
    for number, line in enumerate(path.read_text().splitlines(), 1):
        if line.lstrip().startswith("```"):
            fence = None if fence is not None else line.strip()[3:].strip() or "plain"
            continue
        if fence is not None:
            if fence in ("python", "yaml"):
                continue
            text = pending + line.strip()
            if text.endswith("\\"):
                pending, start = text[:-1] + " ", start or number
                continue
            pending = ""
            if fence == "console":
                if not text.startswith("$ "):
                    continue
                text = text[2:]
            text = re.sub(r"\s+#\s.*$", "", text).strip().removesuffix("&").strip()
            output = re.match(r"\S+ \S+: ", text) or "->" in text
            if text.startswith(STARTS) and not output:
                yield start or number, text, True
            start = 0
            continue
        for span in re.findall(r"`([^`\n]+)`", line):
            if span.startswith(STARTS) and not re.match(r"\S+ \S+: ", span):
                yield number, span.strip(), False


CASES = [(path, number, command, whole) for path in DOCS
         for number, command, whole in commands(path)]


def _words(command: str) -> list[str]:
    words = shlex.split(command.replace("…", "..."), comments=False)
    while words and "=" in words[0] and not words[0].startswith("-"):
        words.pop(0)  # VAR=value before the command
    return words


def _subparsers(parser: argparse.ArgumentParser, words: list[str]
                ) -> Iterator[tuple[argparse.ArgumentParser, list[str]]]:
    """The (sub)parsers the leading words name, and the words left: ``a/b`` where a
    command is named gives each of them."""
    actions = [a for a in parser._actions if isinstance(a, argparse._SubParsersAction)]
    if words and actions:
        names = words[0].split("/")
        if all(name in actions[0].choices for name in names):
            for name in names:
                yield from _subparsers(actions[0].choices[name], words[1:])
            return
    yield parser, words


def _options(parser: argparse.ArgumentParser) -> set[str]:
    return {o for a in parser._actions for o in a.option_strings}


def check_rigkit(words: list[str], whole: bool) -> None:
    for parser, rest in _subparsers(build_parser(), words):
        leaf = not any(isinstance(a, argparse._SubParsersAction) for a in parser._actions)
        if not leaf and rest and not rest[0].startswith("-") and rest[0] != "COMMAND":
            raise AssertionError(f"{parser.prog} has no command {rest[0]!r}")
        unknown = [w.split("=")[0] for w in rest
                   if w.startswith("--") and w.split("=")[0] not in _options(parser)]
        assert not unknown, f"{parser.prog} has no option {', '.join(unknown)}"
    if not whole:
        return
    out = io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(out):
        try:
            build_parser().parse_args(words)
        except SystemExit as exc:
            assert exc.code == 0, out.getvalue().strip()


def check_benchmark(words: list[str]) -> None:
    assert words[:2] == [".venv/bin/python", "-m"] and words[2].startswith("benchmarks."), \
        "benchmark scripts run as modules with the checkout's interpreter: " \
        ".venv/bin/python -m benchmarks.NAME"
    name = words[2].split(".", 1)[1]
    assert (ROOT / "benchmarks" / f"{name}.py").is_file(), f"no benchmarks/{name}.py"
    given = {w.split("=")[0] for w in words[3:] if w.startswith("--")}
    if given:
        shown = _help(name)
        missing = sorted(o for o in given if o not in shown)
        assert not missing, f"benchmarks/{name}.py takes no {', '.join(missing)}"


_HELPS: dict[str, str] = {}


def _help(name: str) -> str:
    if name not in _HELPS:
        import importlib

        out = io.StringIO()
        with contextlib.redirect_stdout(out), contextlib.suppress(SystemExit):
            importlib.import_module(f"benchmarks.{name}").main(["--help"])
        _HELPS[name] = out.getvalue()
    return _HELPS[name]


@pytest.mark.parametrize("path, number, command, whole", CASES,
                         ids=[f"{p.name}:{n}" for p, n, _, _ in CASES])
def test_the_command_is_one_that_runs(path: Path, number: int, command: str,
                                      whole: bool) -> None:
    words = _words(command)
    where = f"{path.relative_to(ROOT)}:{number}: {command}"
    assert words, where
    try:
        if words[0] in ("rigkit", ".venv/bin/rigkit"):
            check_rigkit(words[1:], whole and not SYNOPSIS.search(command))
        elif words[0] == "bash" or words[1:2] and words[1].startswith("scripts/"):
            assert words[0] in ("bash", ".venv/bin/python"), \
                "a script of the checkout runs with bash or the checkout's interpreter"
            assert (ROOT / words[1]).is_file(), f"no {words[1]}"
        else:
            check_benchmark(words)
    except AssertionError as exc:
        raise AssertionError(f"{where}\n  {exc}") from None


def test_the_docs_show_commands() -> None:
    assert len(CASES) > 100 and sum(whole for *_, whole in CASES) > 30
    assert any(c.startswith(".venv/bin/python -m benchmarks.") for _, _, c, _ in CASES)


CHEAP = [case[:3] for case in CASES
         if re.fullmatch(r"(\.venv/bin/)?rigkit (rig check rigs/[\w.-]+\.yaml( --range \d+)*"
                         r"|[a-z -]*--help)", case[2])]
"""Commands quick enough to run here: rig checks of the bundled profiles, --help."""


@pytest.mark.parametrize("path, number, command", CHEAP,
                         ids=[f"{p.name}:{n}" for p, n, _ in CHEAP])
def test_a_cheap_command_runs(path: Path, number: int, command: str,
                              monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.chdir(ROOT)
    out = io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(out):
        try:
            code = main(_words(command)[1:])
        except SystemExit as exc:
            code = exc.code
    assert code in (0, 1), f"{path.name}:{number}: {command}\n{out.getvalue()[-500:]}"


def test_the_readme_set_up_is_what_scripts_do() -> None:
    """The README's first commands are the set-up every other command assumes."""
    text = (ROOT / "README.md").read_text()
    assert "bash scripts/example.sh" in text and "bash scripts/test.sh" in text
    done = subprocess.run(["bash", "-n", str(ROOT / "scripts" / "setup.sh")],
                          capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    assert sys.executable  # the suite itself runs in the checkout's .venv
