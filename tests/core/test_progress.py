"""The progress display: short plain lines off a terminal, rich bars on one, quiet."""

from __future__ import annotations

import io

from rigkit.core.progress import Progress


class Terminal(io.StringIO):
    def isatty(self) -> bool:
        return True


def test_plain_lines_one_per_stage_and_quarter() -> None:
    out = io.StringIO()
    with Progress("process", ["s1", "s2"], file=out) as progress:
        for i in range(101):
            progress.update("s1", i / 100, "matching" if i < 50 else "stereo")
        progress.print("    ok s1")
    lines = out.getvalue().splitlines()
    # matching at 0 %, 25 %; stereo at 50 %, 75 %, 100 %; then the printed line.
    assert [line.split("] ", 1)[1].split(" (")[0] for line in lines[:-1]] == [
        "process: s1: matching 0%",
        "process: s1: matching 25%",
        "process: s1: stereo 50%",
        "process: s1: stereo 75%",
        "process: s1: stereo 100%",
    ]
    assert lines[-1] == "    ok s1"
    assert lines[-2].startswith("[ 50% ETA ")  # s2 has not started: half of all work done
    assert "\x1b" not in out.getvalue()  # no terminal codes in a log


def test_plain_lines_without_stages() -> None:
    out = io.StringIO()
    progress = Progress("synth", ["left"], file=out)
    for i in range(11):
        progress("left", i / 10)
    assert len(out.getvalue().splitlines()) == 5  # 0, 25, 50, 75, 100 %
    assert out.getvalue().splitlines()[-1].split("] ")[1].startswith("synth: left 100%")


def test_quiet_prints_only_the_lines_given() -> None:
    out = io.StringIO()
    with Progress("depth", ["left.png"], quiet=True, file=out) as progress:
        progress.update("left.png", 0.5, "stereo")
        progress.print("result")
    assert out.getvalue() == "result\n"


def test_terminal_shows_bars_with_stage_and_eta() -> None:
    out = Terminal()
    with Progress("process", ["s1", "s2"], file=out) as progress:
        progress.update("s1", 0.5, "stereo")
        progress.print("    ok s0")
        progress.done("s2")
    text = out.getvalue()
    assert "process: s1 (stereo)" in text and "process: all" in text
    assert "50%" in text and "75%" in text  # s1, and the overall bar after s2 finished
    assert "    ok s0" in text


def test_a_session_named_with_markup_and_escapes_is_shown_as_it_is() -> None:
    """A session folder from someone else named ``[a="b]x`` ended `rigkit process` on a
    terminal (a markup error in the bar's description), and its escapes reached the
    terminal (issue 46)."""
    name = '[a="b]x\x1b]0;owned\x07'
    for out in (Terminal(), io.StringIO()):
        with Progress("process", [name], file=out) as progress:
            progress.update(name, 0.5, "stereo")
            progress.print(f"FAILED {name}: \x1b[2J")
        text = out.getvalue()
        assert '[a="b]x\\x1b]0;owned\\x07' in text and "\\x1b[2J" in text
        assert "owned\x07" not in text and "\x1b[2J" not in text
