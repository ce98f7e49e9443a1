"""`rigkit field` refuses bad arguments with one line, before any screen opens."""

from __future__ import annotations

from pathlib import Path

import pytest

from rigkit.cli import main

ROOT = Path(__file__).resolve().parents[2]


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["{tmp}/new"], "{tmp}/new: not a session; give --rig PROFILE to create it"),
        (["--watch", "{tmp}/card"], "--watch {tmp}/card: no such folder"),
        (["{tmp}/new", "--rig", "{tmp}/rig.yaml"], "--rig {tmp}/rig.yaml: no such file"),
        (["--protocol", "morse"], None),
    ],
)
def test_bad_arguments_are_one_line(tmp_path: Path, capsys: pytest.CaptureFixture[str],
                                    args: list[str], message: str | None) -> None:
    code = main(["field", *(a.format(tmp=tmp_path) for a in args)])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1
    if message is None:  # the protocol registry's own message
        assert err[0].startswith("rigkit field: error: ") and "morse" in err[0]
    else:
        assert err == [f"rigkit field: error: {message.format(tmp=tmp_path)}"]


def test_a_bad_rig_profile_names_the_file_and_creates_nothing(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    rig = tmp_path / "rig.yaml"
    rig.write_text("version: 1\nname: x\n")
    assert main(["field", str(tmp_path / "new"), "--rig", str(rig)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and str(rig) in err[0]
    assert not (tmp_path / "new" / "session.yaml").exists()


def test_the_terminal_is_asked_what_it_draws_before_the_app_reads_it(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Before: textual-image was first imported by the app's worker, after the app took
    the terminal's input; its question's answer went to the app, and in a real terminal
    ``rigkit field SESSION`` stayed on "loading ..." for ever."""
    import sys

    from rigkit.capture import create_session
    from rigkit.tui import app as field_app

    seen: list[bool] = []
    monkeypatch.delitem(sys.modules, "textual_image.renderable", raising=False)
    monkeypatch.setattr(field_app.FieldApp, "run",
                        lambda self: seen.append("textual_image.renderable" in sys.modules))
    session = create_session(tmp_path / "s", ROOT / "rigs" / "p1000-tripod.yaml")
    assert main(["field", str(session.path)]) == 0
    assert seen == [True]
