"""An export stopped by SIGTERM cleans its staging as after Ctrl-C, and staging left by
a process that was killed outright is removed by the next export (issue 36)."""

from __future__ import annotations

import os
import signal
from pathlib import Path

import pytest

from rigkit.cli import main
from rigkit.core.files import STAGING_MARK, staged_files


def test_sigterm_during_an_export_leaves_nothing_behind(
    processed_small: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str]
) -> None:
    def killed(*args: object, **kwargs: object) -> None:
        os.kill(os.getpid(), signal.SIGTERM)

    monkeypatch.setattr("rigkit.export.run.write_tiff", killed)
    out = tmp_path / "out"
    out.mkdir()
    before = signal.getsignal(signal.SIGTERM)
    assert main(["export", str(processed_small), "--out", str(out), "--format",
                 "ply,tif", "--quiet"]) == 143
    assert capsys.readouterr().err.strip() == "rigkit export: terminated"
    assert list(out.iterdir()) == []  # no staging folder, no half export
    assert signal.getsignal(signal.SIGTERM) is before  # the handler is given back


def test_staging_of_a_dead_export_is_removed_by_the_next(tmp_path: Path) -> None:
    dead = tmp_path / ".rigkit-999999999-abcd"  # no such process
    (dead / "half.las").parent.mkdir()
    (dead / "half.las").write_bytes(b"x" * 100)
    (dead / STAGING_MARK).write_bytes(b"")  # as staged_files marks its own
    live = tmp_path / f".rigkit-{os.getpid()}-efgh"  # another export of this process
    live.mkdir()
    (live / STAGING_MARK).write_bytes(b"")
    other = tmp_path / ".rigkit-notes"  # not a staging folder's name
    other.mkdir()
    users = tmp_path / ".rigkit-999999999-mybackup"  # a staging folder's name, not one
    (users / "important.txt").parent.mkdir()  # (before: removed with what it held)
    (users / "important.txt").write_text("keep")
    with staged_files(tmp_path) as staging:
        (staging / "new.txt").write_text("new")
    assert not dead.exists() and live.is_dir() and other.is_dir()
    assert (users / "important.txt").read_text() == "keep"
    assert (tmp_path / "new.txt").read_text() == "new"
    assert not (tmp_path / STAGING_MARK).exists()  # the mark is never an output
