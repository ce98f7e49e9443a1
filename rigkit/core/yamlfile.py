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
import reprlib
import stat
from collections.abc import Callable, Hashable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, TypeVar

import yaml

from rigkit.errors import InputError

MAX_YAML_BYTES = 4 << 20
"""The largest YAML file rigkit reads (a session with thousands of readings is ~1 MB)."""


def read_strict_yaml(path: Path, what: str, max_bytes: int = MAX_YAML_BYTES) -> Any:
    """Parse a YAML file, rejecting duplicate keys and alias bombs; InputError names the file
    (``what`` it should be) and the line and column of a syntax error. An empty file is
    an error; so is anything but a regular file (a device such as /dev/zero, a FIFO
    that would block) and a file over ``max_bytes``."""
    path = Path(path)
    text = _read_bounded(path, what, max_bytes)
    try:
        data = yaml.load(text, Loader=_StrictLoader)
    except yaml.MarkedYAMLError as exc:
        mark = exc.problem_mark
        where = f" (line {mark.line + 1}, column {mark.column + 1})" if mark else ""
        problem = exc.problem or exc.context or "syntax error"
        raise InputError(f"{path}: not valid YAML: {problem}{where}") from None
    except yaml.YAMLError as exc:
        raise InputError(f"{path}: not valid YAML: {exc}") from None
    except RecursionError:  # the parser recurses once per level
        data = _TOO_DEEP
    if data is None:
        raise InputError(f"{path}: the {what} is empty")
    if data is _TOO_DEEP or _depth(data) > MAX_YAML_DEPTH:
        raise InputError(f"{path}: not a {what}: lists or mappings nested more than "
                         f"{MAX_YAML_DEPTH} deep")
    return data


MAX_YAML_DEPTH = 32
"""The deepest nesting of lists and mappings rigkit reads (its files need 5 or 6):
deeper, a file of a few KB could exhaust Python's recursion in whatever walks it."""
_TOO_DEEP = object()


def _depth(data: Any) -> int:
    """How deep lists and mappings nest in ``data`` (0: a scalar), without recursion."""
    deepest, level = 0, [(data, 0)]
    while level:
        value, depth = level.pop()
        children = (value.values() if isinstance(value, dict)
                    else value if isinstance(value, list) else None)
        if children is None:
            deepest = max(deepest, depth)
            continue
        deepest = max(deepest, depth + 1)
        if deepest > MAX_YAML_DEPTH:
            return deepest
        level.extend((child, depth + 1) for child in children)
    return deepest


def _read_bounded(path: Path, what: str, max_bytes: int) -> str:
    """The text of ``path``, a regular file of at most ``max_bytes``; InputError otherwise."""
    try:
        info = path.stat()
    except FileNotFoundError:
        raise InputError(f"{path}: no such {what}") from None
    except OSError as exc:
        raise InputError(f"{path}: cannot read the {what} ({exc.strerror})") from None
    if not stat.S_ISREG(info.st_mode):
        raise InputError(f"{path}: not a regular file (a device, FIFO or folder); give the "
                         f"{what}'s YAML file")
    try:
        with path.open("rb") as handle:
            data = handle.read(max_bytes + 1)
    except OSError as exc:
        raise InputError(f"{path}: cannot read the {what} ({exc.strerror})") from None
    if len(data) > max_bytes:
        raise InputError(f"{path}: over {max_bytes >> 20} MB: too large for a {what}")
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError:
        raise InputError(f"{path}: not text (UTF-8 expected): not a {what}") from None


def dump_yaml(data: Any) -> str:
    """``data`` (plain dicts, lists, numbers and text) as YAML that :func:`read_strict_yaml`
    reads back: keys in their given order, nested lists inline, and no aliases (PyYAML
    writes one for an object met twice; the reader refuses them)."""
    return yaml.dump(data, Dumper=_PlainDumper, sort_keys=False, allow_unicode=True,
                     default_flow_style=None)


class _PlainDumper(yaml.SafeDumper):
    def ignore_aliases(self, data: Any) -> bool:
        return True


MAX_YAML_VALUES = 1_000_000
"""The most values a YAML document may stand for once its aliases are expanded."""


_SAFE_LOADER: Any = getattr(yaml, "CSafeLoader", yaml.SafeLoader)
"""libyaml's parser where PyYAML was built with it (its wheels are): ``session show``
of a 3.7 MB session (25 000 targets) took 9.8 s instead of 18 with PyYAML's Python
parser."""


class _StrictLoader(_SAFE_LOADER):
    """A SafeLoader that rejects a key written twice in one mapping (YAML keeps the last)
    and a document whose aliases (``*name``) expand to more than ``MAX_YAML_VALUES``
    values: a few kilobytes of nested aliases stand for billions (a "billion laughs"
    bomb), which anything walking the data would then take minutes and gigabytes for.
    The expanded size is counted on the composed graph, shared nodes once each."""

    def get_single_node(self) -> Any:
        node = super().get_single_node()
        if node is not None and _expanded_size(node, {}) > MAX_YAML_VALUES:
            raise yaml.composer.ComposerError(
                None, None, f"its aliases (*name) expand to over {MAX_YAML_VALUES:,} values",
                node.start_mark)
        return node


def _expanded_size(node: yaml.Node, known: dict[int, int]) -> int:
    """How many values ``node`` stands for with every alias written out (memoised by
    node: an alias is the node it names, met again)."""
    if id(node) in known:
        return known[id(node)]
    known[id(node)] = 1  # a node that contains itself counts once
    if isinstance(node, yaml.SequenceNode):
        size = 1 + sum(_expanded_size(child, known) for child in node.value)
    elif isinstance(node, yaml.MappingNode):
        size = 1 + sum(_expanded_size(k, known) + _expanded_size(v, known)
                       for k, v in node.value)
    else:
        size = 1
    known[id(node)] = min(size, MAX_YAML_VALUES + 1)
    return known[id(node)]


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


_SHOW = reprlib.Repr()
_SHOW.maxlevel, _SHOW.maxlist, _SHOW.maxdict, _SHOW.maxstring, _SHOW.maxother = 2, 4, 4, 50, 50


def show(value: Any) -> str:
    """A short repr of ``value`` for error messages: at most 60 characters, built from a
    bounded part of it (``reprlib``), so a huge value costs no more than a small one."""
    shown = _SHOW.repr(value)
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
            if isinstance(value, str) and _exponent_text(value):
                hint = (f" (YAML reads {value} as text: write its mantissa with a point, "
                        f"e.g. {_with_point(value)})")
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


def _exponent_text(text: str) -> bool:
    """Whether ``text`` is a number in exponent form YAML 1.1 takes for text (``1e7``,
    ``5E-3``: no point in the mantissa)."""
    mantissa, _, exponent = text.strip().lower().partition("e")
    return bool(exponent) and "." not in mantissa and \
        mantissa.lstrip("+-").isdigit() and exponent.lstrip("+-").isdigit()


def _with_point(text: str) -> str:
    """``text`` (:func:`_exponent_text`) as YAML reads a number: ``1e7`` -> ``1.0e+7``."""
    mantissa, _, exponent = text.strip().lower().partition("e")
    sign = "" if exponent[:1] in "+-" else "+"
    return f"{mantissa}.0e{sign}{exponent}"
