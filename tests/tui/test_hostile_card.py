"""A card folder and a session from someone else, in ``rigkit field`` (issue 46): names
that hold markup or terminal escapes are shown as they are, never obeyed; a link out
of the card folder, an entry that cannot be read and a name that is not UTF-8 are said
in one line and skipped, and watching goes on; a ``field_step`` the TUI does not know
(empty, or a newer rigkit's) opens the first position that needs a frame, saying why,
and leaves the session usable by every other command."""

from __future__ import annotations

import os
import threading
from pathlib import Path

import pytest
import yaml

from rigkit.capture import create_session, load_session
from rigkit.capture.field import frames_at, resume_note, resume_step
from rigkit.cli import main
from rigkit.synth.demo import Demo
from rigkit.tui import watch
from rigkit.tui.app import FieldApp
from rigkit.tui.config import FieldConfig
from rigkit.tui.screens import PositionScreen
from tests.tui.conftest import SETTLE_S, opened, synchronous, text, wait_for, write_frame

SIZE = (80, 24)
HOSTILE = '[a="b]x\x1b]0;owned\x07\x1b[2J.png'
"""A frame file's name that is Textual markup and holds escapes that would retitle the
terminal and clear it."""


def _said(app: FieldApp) -> str:
    return "\n".join(str(n.message) for n in app._notifications)


def _arrived(folder: Path, seconds: float, make) -> tuple[list[Path], list[str]]:
    """What :func:`watch.arrivals` yields and says while ``make()`` changes ``folder``."""
    stop, said = threading.Event(), []
    threading.Timer(seconds, stop.set).start()
    threading.Timer(0.2, make).start()
    return list(watch.arrivals(folder, stop, settle_s=0.2, say=said.append)), said


def test_links_unreadable_folders_and_undecodable_names_are_said_and_skipped(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    card, elsewhere = tmp_path / "card", tmp_path / "elsewhere"
    (card / "DCIM" / "locked").mkdir(parents=True)
    elsewhere.mkdir()
    (elsewhere / "DSCN9999.PNG").write_bytes(b"x" * 100)
    real_scandir = os.scandir

    def scandir(path):  # as a folder the user may not read (the tests run as root)
        if str(path).endswith("locked"):
            raise PermissionError(13, "Permission denied")
        return real_scandir(path)

    monkeypatch.setattr(watch.os, "scandir", scandir)

    def camera() -> None:
        (card / "DCIM" / "link").symlink_to(elsewhere, target_is_directory=True)
        (card / "DCIM" / "frame.png").symlink_to(elsewhere / "DSCN9999.PNG")
        (card / os.fsdecode(b"DSC\xff.PNG")).write_bytes(b"x" * 100)
        (card / "DCIM" / HOSTILE).write_bytes(b"x" * 100)

    arrived, said = _arrived(card, 1.5, camera)
    assert arrived == [card / "DCIM" / HOSTILE]  # the only frame file of the card's own
    assert len(said) == len(set(said)) == 4, said  # each said once, not every walk
    assert any("locked: cannot be read (Permission denied)" in line for line in said)
    assert sum("a link; rigkit follows no link" in line for line in said) == 2
    assert any("DSC\\udcff.PNG: its name is not UTF-8" in line for line in said)
    assert all(line.isprintable() for line in said)


@synchronous
async def test_a_card_file_named_with_markup_and_escapes_is_added_and_shown_as_it_is(
    demo: Demo,
) -> None:
    """Before: such a name raised a markup error that ended the TUI (and every reopen
    ended it again), and its escapes retitled and cleared the terminal."""
    session = create_session(demo.capture / "field-1", demo.rig).path
    app = FieldApp(FieldConfig(capture=demo.capture, session=session, watch=demo.card,
                               graphics=False, settle_s=SETTLE_S))
    async with app.run_test(size=SIZE) as pilot:
        await opened(pilot, app)
        await pilot.press("n")
        await wait_for(pilot, lambda: isinstance(app.screen, PositionScreen), "the left screen")
        (demo.card / "outside").symlink_to(demo.scene, target_is_directory=True)
        (demo.card / os.fsdecode(b"DSC\xff.PNG")).write_bytes(b"not UTF-8")
        write_frame(demo.card / HOSTILE, demo.scene / "left.png", iso=100)
        await wait_for(pilot, lambda: "✔" in text(app, "#checks"), "the frame's checks")
        shown = text(app, "#status")
        assert '[a="b]x_]0;owned__[2J.png' in shown and "\x1b" not in shown
        await wait_for(pilot, lambda: "not UTF-8" in _said(app), "the undecodable name said")
        assert "a link; rigkit follows no link" in _said(app) and "\x1b" not in _said(app)
        assert app.is_running
    frames = frames_at(load_session(session), "left")
    assert [Path(f.file).name for f in frames] == ['[a="b]x_]0;owned__[2J.png']
    assert "\\x1b]0;owned\\x07" in frames[0].source  # the name as it was, written out
    assert main(["session", "show", str(session)]) == 0  # and the session stays usable


@pytest.mark.parametrize("step, why", [(None, "is empty"), ("", "is empty"),
                                       ("calibrate", "'calibrate' is no step")])
def test_an_unknown_field_step_leaves_the_session_usable(
    demo: Demo, step: str | None, why: str, capsys: pytest.CaptureFixture[str]
) -> None:
    path = demo.session
    data = yaml.safe_load((path / "session.yaml").read_text())
    data["field_step"] = step
    (path / "session.yaml").write_text(yaml.safe_dump(data))
    session = load_session(path)
    assert resume_step(session) == "left"  # the first position that needs a frame
    assert why in resume_note(session) and "starting at left" in resume_note(session)
    assert main(["session", "show", str(path)]) == 0
    assert main(["session", "add-target", str(path), "--name", "T", "--pixel", "5", "5",
                 "--range-m", "300"]) == 0
    assert load_session(path).field_step == (step or "")  # kept for a rigkit that knows it


@synchronous
async def test_the_tui_opens_an_unknown_step_at_the_first_position_and_says_why(
    demo: Demo,
) -> None:
    path = demo.session
    data = yaml.safe_load((path / "session.yaml").read_text())
    data["field_step"] = "align-horizon"  # a step a newer rigkit might add
    (path / "session.yaml").write_text(yaml.safe_dump(data))
    app = FieldApp(FieldConfig(capture=demo.capture, session=path, graphics=False,
                               settle_s=SETTLE_S))
    async with app.run_test(size=SIZE) as pilot:
        await wait_for(pilot, lambda: isinstance(app.screen, PositionScreen)
                       and app.screen.position == "left", "the left screen")
        await wait_for(pilot, lambda: "'align-horizon' is no step" in _said(app), "why")
        assert app.is_running
    assert load_session(path).field_step == "left"
