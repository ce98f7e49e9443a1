"""The one table formatter."""

from __future__ import annotations

from rigkit.core.tables import render_table


def test_columns_align_under_a_rule() -> None:
    text = render_table(
        ["name", "value m", "status"],
        [["a", "1.50", "ok"], ["longer", "1234.50", "no_estimate"], None, ["mean", "618.00", ""]],
        left=[0, 2],
    )
    assert text.splitlines() == [
        "name    value m  status",
        "-" * 28,
        "a          1.50  ok",
        "longer  1234.50  no_estimate",
        "-" * 28,
        "mean     618.00",
    ]


def test_two_line_header_indented_without_rules() -> None:
    text = render_table(["range\nm", "angle\ndeg"], [["100", "1.146"], ["300", "0.382"]],
                        indent=2, rule=False)
    assert text.splitlines() == [
        "  range  angle",
        "      m    deg",
        "    100  1.146",
        "    300  0.382",
    ]


def test_no_trailing_spaces_and_no_terminal_codes() -> None:
    text = render_table(["a", "b"], [["x", ""], ["[bold]y[/bold]", "2"]], left=[0, 1])
    assert all(line == line.rstrip() for line in text.splitlines())
    assert "[bold]y[/bold]" in text and "\x1b" not in text  # cells are not markup


def test_visible_writes_out_control_characters_but_lines_and_tabs() -> None:
    from rigkit.core.tables import visible

    assert visible("note\x1b]0;owned\x07\x1b[2J end\nnext\tcol\x7f") == (
        "note\\x1b]0;owned\\x07\\x1b[2J end\nnext\tcol\\x7f")
