"""The one rule for outputs (rigkit.core.outputs; docs/sessions.md, "Where rigkit writes"),
held against every command's output options as the argparse parser declares them: each
option of an output type, in every subcommand, is given each place no output may be
(inside a session's raw/, onto session.yaml or a session's logs, a link, a FIFO, a
device, a file rigkit did not write). Each is refused in one line naming the place,
exit status 2, and the place is as it was. An option that names a file or folder must
say whether the command reads or writes it, so a new output option cannot skip the
rule."""

from __future__ import annotations

import argparse
import hashlib
import os
import stat
from collections.abc import Callable, Iterator
from pathlib import Path

import pytest

from rigkit.capture.comparisons import LOG_NAME
from rigkit.capture.model import DERIVED_DIR, HISTORY_FILE, RAW_DIR, SESSION_FILE
from rigkit.capture.results import RESULTS_DIR
from rigkit.cli import build_parser, main
from rigkit.commands import OutputPath
from rigkit.core.outputs import LEDGER, SESSION_KEPT
from tests.conftest import copy_session

READ = {
    ("depth", "left"), ("depth", "right"), ("depth", "back"), ("depth", "rig"),
    ("synth", "rig"), ("eval", "scenes"), ("eval", "depth_dir"), ("rig", "check", "profile"),
    ("rig", "check", "capture"), ("rig", "calibrate", "sessions"),
    ("rig", "calibrate", "check_session"),
    ("rangefinder", "read", "rig"), ("rangefinder", "log", "rig"),
    ("session", "add-frame", "session"), ("session", "add-frame", "file"),
    ("session", "new", "rig"), ("session", "add-target", "session"),
    ("session", "add-target", "rig"), ("session", "remove-reading", "session"),
    ("session", "remove-target", "session"), ("session", "remove-frame", "session"),
    ("session", "show", "session"), ("session", "set-position", "session"),
    ("session", "set-rig", "session"), ("session", "set-rig", "rig"),
    ("process", "sessions"), ("report", "sessions"), ("export", "source"),
    ("field", "rig"), ("field", "watch"),
}
"""Every option naming a file or folder that a command reads (or changes through the
session commands' own rules), by subcommand and destination; every other such option
must be of an output type (rigkit.commands.output_file, output_folder, output_log)."""

_PATHISH = ("FILE", "DIR", "PATH", "SESSION", "PROFILE", "SCENE")


def _subparsers(parser: argparse.ArgumentParser, path: tuple[str, ...] = ()
                ) -> Iterator[tuple[tuple[str, ...], argparse.ArgumentParser]]:
    """Every (sub)command's parser, with the words that choose it."""
    subs = [a for a in parser._actions if isinstance(a, argparse._SubParsersAction)]
    if not subs:
        yield path, parser
    for sub in subs:
        for name, child in sub.choices.items():
            yield from _subparsers(child, (*path, name))


def _commands() -> list[tuple[tuple[str, ...], argparse.ArgumentParser]]:
    return list(_subparsers(build_parser()))


def _names_a_path(action: argparse.Action) -> bool:
    """Whether an option takes a file or folder, by its type, metavar or name (a flag
    or a number takes none)."""
    if action.type is Path or isinstance(action.type, OutputPath):
        return True
    if action.nargs == 0 or action.type not in (None, str):
        return False
    words = f"{action.metavar or ''} {action.dest}".upper()
    return any(w in words for w in _PATHISH) or action.dest in ("out", "output", "csv",
                                                               "raw_log", "log")


def _outputs() -> list[tuple[tuple[str, ...], argparse.Action]]:
    return [(path, action) for path, parser in _commands() for action in parser._actions
            if isinstance(action.type, OutputPath)]


def test_every_option_naming_a_path_is_declared_read_or_written() -> None:
    undeclared = [(*path, action.dest) for path, parser in _commands()
                  for action in parser._actions
                  if _names_a_path(action) and not isinstance(action.type, OutputPath)
                  and (*path, action.dest) not in READ]
    assert undeclared == [], "declare these as outputs (an output type) or add them to READ"
    outputs = {(*path, action.dest) for path, action in _outputs()}
    assert outputs == {
        ("depth", "out"), ("synth", "out_dir"), ("eval", "csv"),
        ("rig", "calibrate", "out"), ("rangefinder", "read", "raw_log"),
        ("rangefinder", "log", "raw_log"), ("rangefinder", "log", "output"),
        ("session", "new", "session"), ("report", "out"), ("export", "out"),
        ("field", "session"), ("field", "capture"),
        ("experiments", "table1", "out"), ("experiments", "bas-relief", "out"),
    }


def test_the_session_parts_kept_are_the_sessions_own() -> None:
    assert SESSION_KEPT == {SESSION_FILE, RAW_DIR, DERIVED_DIR, RESULTS_DIR, HISTORY_FILE,
                            LOG_NAME}


def _argv(path: tuple[str, ...], parser: argparse.ArgumentParser, target: argparse.Action,
          value: Path, dummy: Path) -> list[str]:
    """A command line that parses: every required argument given a dummy (a number, the
    first choice, a file name), ``target`` given ``value``."""
    argv = list(path)
    for action in parser._actions:
        if action.dest == target.dest:
            argv += [*action.option_strings[-1:], str(value)]
            continue
        if not (action.required or not action.option_strings) or isinstance(
                action, argparse._HelpAction) or action.nargs == "?":
            continue
        if action.choices:
            text = str(next(iter(action.choices)))
        elif action.type not in (None, Path) and not isinstance(action.type, OutputPath):
            text = "1"
        else:
            text = str(dummy)
        argv += [*action.option_strings[-1:], text]
    return argv


Target = Callable[[Path, Path], Path]


def _in_raw_existing(session: Path, tmp: Path) -> Path:
    return session / RAW_DIR / "left.png"


def _in_raw_new(session: Path, tmp: Path) -> Path:
    return session / RAW_DIR / "new" / "out.npy"


def _raw(session: Path, tmp: Path) -> Path:
    return session / RAW_DIR


def _session_yaml(session: Path, tmp: Path) -> Path:
    return session / SESSION_FILE


def _history(session: Path, tmp: Path) -> Path:
    return session / HISTORY_FILE


def _comparisons(session: Path, tmp: Path) -> Path:
    return session / LOG_NAME


def _staging(session: Path, tmp: Path) -> Path:
    return session / ".staging" / "x.npy"


def _through_raw_link(session: Path, tmp: Path) -> Path:
    """A folder outside the session that is a link to its raw/."""
    link = tmp / "frames"
    link.symlink_to(session / RAW_DIR, target_is_directory=True)
    return link / "out.npy"


def _link_to_file(session: Path, tmp: Path) -> Path:
    precious = tmp / "precious.txt"
    precious.write_text("do not touch\n")
    link = tmp / "link.out"
    link.symlink_to(precious)
    return link


def _link_to_folder(session: Path, tmp: Path) -> Path:
    (tmp / "elsewhere").mkdir()
    link = tmp / "folder-link"
    link.symlink_to(tmp / "elsewhere", target_is_directory=True)
    return link


def _fifo(session: Path, tmp: Path) -> Path:
    os.mkfifo(tmp / "fifo.out")
    return tmp / "fifo.out"


def _device(session: Path, tmp: Path) -> Path:
    return Path("/dev/null")


def _not_rigkits(session: Path, tmp: Path) -> Path:
    mine = tmp / "mine.out"
    mine.write_text("my own notes\n")
    return mine


PLACES: list[Target] = [_in_raw_existing, _in_raw_new, _raw, _session_yaml, _history,
                        _comparisons, _staging, _through_raw_link, _link_to_file,
                        _link_to_folder, _fifo, _device, _not_rigkits]


def _state(*roots: Path) -> dict[str, object]:
    """What is at and under ``roots``: each entry's kind, a link's target, a file's hash."""
    seen: dict[str, object] = {}
    for root in roots:
        for path in [root, *(root.rglob("*") if root.is_dir() and not root.is_symlink()
                             else [])]:
            info = os.lstat(path)
            if stat.S_ISLNK(info.st_mode):
                seen[str(path)] = ("link", os.readlink(path))
            elif stat.S_ISREG(info.st_mode):
                seen[str(path)] = hashlib.sha256(path.read_bytes()).hexdigest()
            else:
                seen[str(path)] = stat.S_IFMT(info.st_mode)
    return seen


@pytest.fixture(scope="module")
def session_copy(small_session: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A session no test changes (each refusal leaves it as it was)."""
    return copy_session(small_session, tmp_path_factory.mktemp("kept"))


@pytest.mark.parametrize("place", PLACES, ids=lambda p: p.__name__.strip("_"))
@pytest.mark.parametrize("option", _outputs(), ids=lambda o: "-".join((*o[0], o[1].dest)))
def test_no_output_option_writes_where_no_output_may_go(
    option: tuple[tuple[str, ...], argparse.Action], place: Target, session_copy: Path,
    tmp_path: Path, capsys: pytest.CaptureFixture[str],
) -> None:
    path, action = option
    parser = dict(_commands())[path]
    target = place(session_copy, tmp_path)
    before = _state(session_copy, tmp_path)
    code = main(_argv(path, parser, action, target, tmp_path / "in.dat"))
    err = capsys.readouterr().err.strip()
    assert code == 2 and len(err.splitlines()) == 1, err
    assert str(target) in err or str(target.parent) in err, err
    assert _state(session_copy, tmp_path) == before


def test_force_replaces_only_a_profile_rigkit_wrote(
    processed_session: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "rig.yaml"
    calibrate = ["rig", "calibrate", str(processed_session), "--out", str(out)]
    assert main(calibrate) == 0
    assert main(calibrate) == 2
    assert "exists; give --force" in capsys.readouterr().err
    assert main([*calibrate, "--force"]) == 0  # its own profile
    with out.open("a") as edited:  # edited since: no longer the file rigkit wrote
        edited.write("# tuned by hand\n")
    mine = tmp_path / "mine.yaml"
    mine.write_text("name: my own profile\n")
    for path in (out, mine):
        kept = path.read_bytes()
        capsys.readouterr()
        assert main(["rig", "calibrate", str(processed_session), "--out", str(path),
                     "--force"]) == 2
        err = capsys.readouterr().err
        assert "was not written by rigkit" in err and len(err.splitlines()) == 1
        assert path.read_bytes() == kept


def test_a_folder_output_writes_over_none_of_its_files_it_did_not_write(
    processed_session: Path, scene_dir: Path, tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
) -> None:
    """The names a command writes inside its folder (an export's <session>.tif, a
    report's report.txt, a depth run's d.json beside d.npy, bas-relief's table) are held
    to the rule before any work."""
    session = copy_session(processed_session, tmp_path)
    frames = [str(scene_dir / f"{v}.png") for v in ("left", "right", "back")]
    cases = [
        (["export", str(session), "--format", "tif", "--out"], f"{session.name}.tif"),
        (["report", str(session), "--out"], "report.txt"),
        (["experiments", "bas-relief", "--runs", "1", "--out"], "basrelief.json"),
        (["experiments", "table1", "--scenes", "1", "--width", "160", "--height", "120",
          "--out"], "table1.png"),
    ]
    for argv, name in cases:
        out = tmp_path / f"out-{argv[0]}-{name}"
        out.mkdir()
        (out / name).write_text("mine\n")
        assert main([*argv, str(out)]) == 2, argv
        err = capsys.readouterr().err
        assert f"{out / name} exists and was not written by rigkit" in err, err
        assert sorted(p.name for p in out.iterdir()) == [name]
        assert (out / name).read_text() == "mine\n"
    (tmp_path / "d.json").write_text("{}\n")
    assert main(["depth", *frames, "--out", str(tmp_path / "d.npy"), "--focal-px", "9159",
                 "--baseline-lr", "2", "--baseline-lb", "2", "--quiet"]) == 2
    assert "d.json exists and was not written by rigkit" in capsys.readouterr().err
    assert not (tmp_path / "d.npy").exists()


def test_what_rigkit_wrote_it_writes_again_and_the_ledger_says_so(
    processed_session: Path, tmp_path: Path
) -> None:
    """A second export into the same folder replaces the first; the ledger names each
    file with its inode, size and time, and what wrote it."""
    import json

    out = tmp_path / "out"
    argv = ["export", str(processed_session), "--format", "tif", "--out", str(out)]
    assert main(argv) == 0
    first = os.stat(out / f"{processed_session.name}.tif")
    assert main(argv) == 0
    second = os.stat(out / f"{processed_session.name}.tif")
    assert second.st_ino != first.st_ino  # a new file renamed over the old one
    ledger = json.loads((out / LEDGER).read_text())["files"]
    assert ledger[f"{processed_session.name}.tif"] == {
        "inode": second.st_ino, "size": second.st_size, "mtime_ns": second.st_mtime_ns,
        "by": "export"}
