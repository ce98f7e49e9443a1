"""scripts/setup.sh (issue 46): a usage line without arguments; a checkout at a path
with spaces (pip split PIP_CONSTRAINT there and nothing installed); a virtual
environment whose python link dangles, made anew instead of ``[Errno 2]``. The runs are
offline (``PIP_NO_INDEX``): what is checked is what setup.sh hands pip, not what pip
then finds."""

from __future__ import annotations

import os
import shutil
import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]


def _checkout(where: Path) -> Path:
    """The files setup.sh uses, copied to ``where``."""
    for name in ("scripts/setup.sh", "requirements/lock.txt", "pyproject.toml"):
        (where / name).parent.mkdir(parents=True, exist_ok=True)
        shutil.copy(ROOT / name, where / name)
    return where


def _setup(checkout: Path, *args: str) -> subprocess.CompletedProcess[str]:
    env = {**os.environ, "PIP_NO_INDEX": "1", "PIP_DISABLE_PIP_VERSION_CHECK": "1"}
    env.pop("PIP_CONSTRAINT", None)
    return subprocess.run(["bash", str(checkout / "scripts" / "setup.sh"), *args],
                          capture_output=True, text=True, env=env, timeout=300)


def test_without_arguments_it_says_how_to_call_it() -> None:
    done = _setup(ROOT)
    assert done.returncode == 2
    assert done.stderr.startswith("usage: bash scripts/setup.sh VENV") and \
        len(done.stderr.splitlines()) == 1


@pytest.mark.slow
def test_a_checkout_at_a_path_with_spaces_hands_pip_the_whole_lock(tmp_path: Path) -> None:
    checkout = _checkout(tmp_path / "with space" / "rk")
    done = _setup(checkout, ".venv", "")
    assert "Could not open requirements file" not in done.stderr, done.stderr
    assert (checkout / ".venv" / "bin" / "python").exists()


@pytest.mark.slow
def test_a_venv_whose_python_dangles_is_made_anew(tmp_path: Path) -> None:
    checkout = _checkout(tmp_path / "rk")
    venv = checkout / ".venv"
    (venv / "bin").mkdir(parents=True)
    (venv / "pyvenv.cfg").write_text("home = /no/such/python\n")
    (venv / "bin" / "python").symlink_to("/no/such/python/bin/python3")
    done = _setup(checkout, ".venv", "")
    assert "does not run" in done.stderr and "making .venv anew" in done.stderr
    assert "Errno 2" not in done.stderr
    assert subprocess.run([str(venv / "bin" / "python"), "-c", ""]).returncode == 0
    (tmp_path / "notes").mkdir()  # a folder that is no venv is never cleared
    (tmp_path / "notes" / "keep.txt").write_text("mine\n")
    done = _setup(checkout, str(tmp_path / "notes"), "")
    assert done.returncode == 2 and "is no virtual environment" in done.stderr
    assert (tmp_path / "notes" / "keep.txt").read_text() == "mine\n"
