"""docs/architecture.md's "What lives where" lists the tree as it is: every module of
each package is named in its row, and no row names a module that is not there (a module
added, moved or removed without the page fails here)."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
PAGE = ROOT / "docs" / "architecture.md"


def listed() -> dict[str, set[str]]:
    """Package folder (``core``, ``tui/screens``) -> the modules its rows name."""
    text = PAGE.read_text()
    table = text[text.index("## What lives where"):text.index("## From frames")]
    packages: dict[str, set[str]] = {}
    package = ""
    for row in table.splitlines():
        cells = [c.strip() for c in row.strip().strip("|").split("|")]
        if len(cells) < 3 or not row.startswith("|") or re.fullmatch(r"-+", cells[0]):
            continue
        first = re.fullmatch(r"`([\w/]+)/`", cells[0])
        if first:
            package = first.group(1)
        elif cells[0]:
            continue  # geometry.py, errors.py; the header
        packages.setdefault(package, set()).update(
            name for name in re.findall(r"`(\w+)`", cells[1]))
    return packages


def tree(package: str) -> set[str]:
    return {p.stem for p in (ROOT / "rigkit" / package).glob("*.py") if p.stem != "__init__"}


LISTED = listed()


def test_every_package_has_a_row() -> None:
    packages = {str(p.parent.relative_to(ROOT / "rigkit"))
                for p in (ROOT / "rigkit").rglob("__init__.py")} - {"."}
    assert packages == set(LISTED)


@pytest.mark.parametrize("package", sorted(set(LISTED) - {"commands"}))
def test_the_row_names_the_packages_modules(package: str) -> None:
    assert LISTED[package] == tree(package), package


def test_every_command_is_two_modules() -> None:
    modules = tree("commands")
    runners = {m.removesuffix("_run") for m in modules if m.endswith("_run")}
    arguments = {m for m in modules if not m.endswith("_run")}
    assert runners <= arguments and "session_position" in arguments
    assert {"depth", "process", "session", "field"} <= runners
