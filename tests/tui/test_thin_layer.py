"""The TUI stays a thin layer: the library and the command line work without Textual,
and `rigkit field` without it says so in one line."""

from __future__ import annotations

import subprocess
import sys

BLOCK_TEXTUAL = """
import importlib.abc, sys

class Block(importlib.abc.MetaPathFinder):
    def find_spec(self, name, path=None, target=None):
        if name.split(".")[0] in ("textual", "textual_image"):
            raise ImportError(f"No module named {name!r}", name=name)
        return None

sys.meta_path.insert(0, Block())
"""

IMPORT_ALL = BLOCK_TEXTUAL + """
import pkgutil, importlib, rigkit
for module in pkgutil.walk_packages(rigkit.__path__, "rigkit."):
    if not module.name.startswith(("rigkit.tui", "rigkit.__main__")):
        importlib.import_module(module.name)
from rigkit.cli import build_parser
build_parser()
assert not any(name.split(".")[0] == "textual" for name in sys.modules)
print("ok")
"""


def _run(code: str, *args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-c", code, *args], capture_output=True, text=True,
                          timeout=120)


def test_library_and_cli_import_without_textual() -> None:
    done = _run(IMPORT_ALL)
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip() == "ok"


def test_field_without_textual_is_one_clear_line() -> None:
    code = BLOCK_TEXTUAL + "from rigkit.cli import main\nsys.exit(main(['field', '--demo']))"
    done = _run(code)
    assert done.returncode == 2
    assert done.stderr.strip().splitlines() == [
        "rigkit field: error: rigkit field needs the TUI packages (textual is missing): "
        "pip install rigkit"
    ]
