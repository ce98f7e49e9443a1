"""The strict YAML reader and the key-path validator."""

from __future__ import annotations

from pathlib import Path

import pytest

from rigkit.core.yamlfile import KeyPath, read_strict_yaml
from rigkit.errors import InputError


def _write(tmp_path: Path, text: str) -> Path:
    path = tmp_path / "file.yaml"
    path.write_text(text, encoding="utf-8")
    return path


def test_reads_mappings_lists_anchors_and_merge_keys(tmp_path: Path) -> None:
    path = _write(tmp_path, "a: &x {b: 1, c: [1, 2]}\nd: {<<: *x, b: 2}\n")
    assert read_strict_yaml(path, "thing") == {
        "a": {"b": 1, "c": [1, 2]},
        "d": {"b": 2, "c": [1, 2]},
    }


def test_duplicate_keys_are_refused_with_line_and_column(tmp_path: Path) -> None:
    path = _write(tmp_path, "a: 1\nb:\n  c: 1\n  c: 2\n")
    with pytest.raises(InputError) as caught:
        read_strict_yaml(path, "thing")
    assert str(caught.value) == f"{path}: not valid YAML: key 'c' appears twice (line 4, column 3)"


def test_syntax_errors_name_line_and_column(tmp_path: Path) -> None:
    path = _write(tmp_path, "a: [1, 2\nb: 3\n")
    with pytest.raises(InputError, match=r"file\.yaml: not valid YAML: .*\(line \d+, column \d+\)"):
        read_strict_yaml(path, "thing")


@pytest.mark.parametrize(
    "text, message",
    [(None, "no such thing"), ("", "the thing is empty"), ("# only a comment\n", "is empty")],
)
def test_missing_and_empty_files(tmp_path: Path, text: str | None, message: str) -> None:
    path = tmp_path / "file.yaml" if text is None else _write(tmp_path, text)
    with pytest.raises(InputError, match=message):
        read_strict_yaml(path, "thing")


def test_errors_name_file_dotted_key_and_value() -> None:
    key = KeyPath(Path("rig.yaml")).child("cameras").child("left").child("focal_length")
    with pytest.raises(InputError) as caught:
        key.child("mm").bounded(-71.3, "mm", 5000)
    assert str(caught.value) == (
        "rig.yaml: cameras.left.focal_length.mm: must be > 0 and <= 5000 mm, got -71.3"
    )
    with pytest.raises(InputError, match=r"targets\[2\]\.pixel: must be a list of two"):
        KeyPath(Path("s.yaml")).child("targets").item(2).child("pixel").pair([1], "u, v")
    with pytest.raises(InputError, match=r"^s\.yaml: \(top level\): must be a mapping"):
        KeyPath(Path("s.yaml")).mapping([1], required=("a",))


def test_unknown_key_suggests_the_nearest() -> None:
    key = KeyPath(Path("rig.yaml"), "baselines.C_lr")
    with pytest.raises(InputError) as caught:
        key.mapping({"value": 2.0, "tolerance_m": 0.01}, required=("value_m", "tolerance_m"))
    assert str(caught.value) == (
        "rig.yaml: baselines.C_lr.value: unknown key; did you mean 'value_m'? "
        "allowed here: value_m, tolerance_m"
    )
    with pytest.raises(InputError, match=r"baselines.C_lr.value_m: missing$"):
        key.mapping({"tolerance_m": 0.01}, required=("value_m", "tolerance_m"))


def test_values() -> None:
    key = KeyPath(Path("f.yaml"), "k")
    assert key.number(3, "m") == 3.0 and isinstance(key.number(3, "m"), float)
    for bad in (True, "2 m", float("nan")):
        with pytest.raises(InputError, match="k: must be a"):
            key.number(bad, "m")
    assert key.positive(0.5, "m") == 0.5
    with pytest.raises(InputError, match="must be a positive number in m, got 0"):
        key.positive(0, "m")
    assert key.integer(7, "px", 10) == 7
    with pytest.raises(InputError, match="between 1 and 10"):
        key.integer(11, "px", 10)
    assert key.line("  name ") == "name" and key.text(" a\nb ", strip=False) == " a\nb "
    with pytest.raises(InputError, match="single-line"):
        key.line("a\nb")
    assert key.sequence(None) == [] and key.sequence([1]) == [1]
    with pytest.raises(InputError, match="must be a list"):
        key.sequence({"a": 1})


@pytest.mark.parametrize("depth", [33, 2000])
def test_nesting_deeper_than_any_rigkit_file_is_one_line(tmp_path: Path, depth: int) -> None:
    """A few KB of brackets: 2000 deep is past libyaml's own limit (and PyYAML's
    recursion, without libyaml), 33 would reach whatever walks the data; both are
    refused as what they are."""
    path = _write(tmp_path, "a: " + "[" * depth + "]" * depth + "\n")
    with pytest.raises(InputError, match="nested more than 32 deep|maximum nesting depth"):
        read_strict_yaml(path, "rig profile")
    deepest: list = []  # the mapping and 31 lists: 32 levels, as deep as is read
    for _ in range(30):
        deepest = [deepest]
    assert read_strict_yaml(_write(tmp_path, "a: " + "[" * 31 + "]" * 31), "x") == {
        "a": deepest}
