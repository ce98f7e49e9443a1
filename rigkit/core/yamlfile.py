"""The one strict YAML reader, and the key-path validator that turns parsed YAML into
typed values with errors a person can act on.

:func:`read_strict_yaml` parses a file with ``yaml.SafeLoader`` but rejects a key
written twice in one mapping (YAML would silently keep the last) and reports syntax
errors with their line and column. :class:`KeyPath` is where a value sits (file and
dotted key, e.g. ``cameras.left.focal_length.mm`` or ``targets[0].pixel``); its
methods check one value each and raise :class:`~rigkit.errors.InputError` on one line
naming the file, the key, what was expected and the value found, with a "did you
mean" for a misspelt key.
"""

from __future__ import annotations

import difflib
import math
from collections.abc import Callable, Hashable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, TypeVar

import yaml

from rigkit.errors import InputError


def read_strict_yaml(path: Path, what: str) -> Any:
    """Parse a YAML file, rejecting duplicate keys; InputError names the file (``what``
    it should be) and the line and column of a syntax error. An empty file is an error."""
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise InputError(f"{path}: no such {what}") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise InputError(f"{path}: cannot read the {what} ({exc})") from None
    try:
        data = yaml.load(text, Loader=_StrictLoader)
    except yaml.MarkedYAMLError as exc:
        mark = exc.problem_mark
        where = f" (line {mark.line + 1}, column {mark.column + 1})" if mark else ""
        problem = exc.problem or exc.context or "syntax error"
        raise InputError(f"{path}: not valid YAML: {problem}{where}") from None
    except yaml.YAMLError as exc:
        raise InputError(f"{path}: not valid YAML: {exc}") from None
    if data is None:
        raise InputError(f"{path}: the {what} is empty")
    return data


class _StrictLoader(yaml.SafeLoader):
    """A SafeLoader that rejects a key written twice in one mapping (YAML keeps the last)."""


def _construct_unique_mapping(loader: _StrictLoader, node: yaml.MappingNode) -> dict[Any, Any]:
    seen: set[Any] = set()
    for key_node, _ in node.value:
        if key_node.tag == "tag:yaml.org,2002:merge":
            continue
        key = loader.construct_object(key_node)
        if not isinstance(key, Hashable):
            break  # construct_mapping reports the unhashable key
        if key in seen:
            raise yaml.constructor.ConstructorError(
                None, None, f"key {key!r} appears twice", key_node.start_mark
            )
        seen.add(key)
    return loader.construct_mapping(node)


_StrictLoader.add_constructor(
    yaml.resolver.BaseResolver.DEFAULT_MAPPING_TAG, _construct_unique_mapping
)


def show(value: Any) -> str:
    """``repr(value)`` cut to 60 characters, for error messages."""
    shown = repr(value)
    return shown if len(shown) <= 60 else shown[:57] + "..."


def unknown_key_problem(key: str, allowed: Sequence[str]) -> str:
    """'unknown key; did you mean ...? allowed here: ...' for a key not in ``allowed``."""
    close = difflib.get_close_matches(key, list(allowed), n=1)
    suggestion = f"did you mean {close[0]!r}? " if close else ""
    return f"unknown key; {suggestion}allowed here: {', '.join(allowed)}"


_T = TypeVar("_T")


@dataclass(frozen=True)
class KeyPath:
    """Where a value sits in a YAML file (file and dotted key), for checks and errors."""

    file: Path
    key: str = ""

    def child(self, name: str) -> KeyPath:
        """The key ``name`` inside this mapping."""
        return KeyPath(self.file, f"{self.key}.{name}" if self.key else name)

    def item(self, index: int) -> KeyPath:
        """The ``index``-th element of this list."""
        return KeyPath(self.file, f"{self.key}[{index}]")

    def error(self, problem: str, value: Any = ...) -> InputError:
        """``<file>: <key>: <problem>, got <value>`` (the value left out when not given)."""
        key = self.key or "(top level)"
        got = "" if value is ... else f", got {show(value)}"
        return InputError(f"{self.file}: {key}: {problem}{got}")

    def mapping(
        self, value: Any, required: Sequence[str], optional: Sequence[str] = ()
    ) -> dict[str, Any]:
        """A mapping with exactly the ``required`` keys and any of the ``optional`` ones."""
        if not isinstance(value, dict):
            raise self.error("must be a mapping of keys to values", value)
        allowed = (*required, *optional)
        for key in value:
            if key not in allowed:
                raise self.child(str(key)).error(unknown_key_problem(str(key), allowed))
        for key in required:
            if key not in value:
                raise self.child(key).error("missing")
        return value

    def optional(
        self, keys: dict[str, Any], name: str, read: Callable[[Any, KeyPath], _T]
    ) -> _T | None:
        """``read(value, key)`` of the key ``name`` of this mapping's ``keys`` when it is
        present, else None."""
        return read(keys[name], self.child(name)) if name in keys else None

    def sequence(self, value: Any) -> list[Any]:
        """A list (``None``, an empty YAML value, is an empty list)."""
        if value is None:
            return []
        if not isinstance(value, list):
            raise self.error("must be a list", value)
        return value

    def number(self, value: Any, unit: str) -> float:
        """A finite real number (not a boolean, not a string with a unit in it)."""
        if isinstance(value, bool) or not isinstance(value, int | float):
            hint = " (the unit is in the key name; write the number only)"
            raise self.error(f"must be a number in {unit}{hint}", value)
        if not math.isfinite(value):
            raise self.error(f"must be a finite number in {unit}", value)
        return float(value)

    def positive(self, value: Any, unit: str) -> float:
        """A finite number > 0."""
        number = self.number(value, unit)
        if not number > 0:
            raise self.error(f"must be a positive number in {unit}", value)
        return number

    def bounded(
        self, value: Any, unit: str, high: float, *, low: float = 0.0, hint: str = ""
    ) -> float:
        """A number in (low, high] (low < value <= high)."""
        number = self.number(value, unit)
        if not low < number <= high:
            why = f" ({hint})" if hint and number > high else ""
            raise self.error(f"must be > {low:g} and <= {high:g} {unit}{why}", value)
        return number

    def integer(self, value: Any, unit: str, high: int) -> int:
        """A whole number in [1, high]."""
        if isinstance(value, bool) or not isinstance(value, int):
            raise self.error(f"must be a whole number of {unit}", value)
        if not 1 <= value <= high:
            raise self.error(f"must be between 1 and {high} {unit}", value)
        return value

    def pair(self, value: Any, names: str) -> tuple[Any, Any]:
        """A two-element list such as ``[width, height]``."""
        if not isinstance(value, list) or len(value) != 2:
            raise self.error(f"must be a list of two numbers [{names}]", value)
        return value[0], value[1]

    def line(self, value: Any) -> str:
        """A non-empty single-line string."""
        if not isinstance(value, str) or not value.strip() or "\n" in value.strip():
            raise self.error("must be a non-empty single-line string", value)
        return value.strip()

    def text(self, value: Any, *, strip: bool = True) -> str:
        """Free text (may span lines); ``strip=False`` keeps it exactly as written."""
        if not isinstance(value, str):
            raise self.error("must be text", value)
        return value.strip() if strip else value
