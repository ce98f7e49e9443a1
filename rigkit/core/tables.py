"""The one table formatter: columns of text laid out by rich, rendered to plain text
(for files, logs, tests and terminals alike).

``render_table(header, rows)`` gives fixed-width columns two spaces apart under a
header and a rule of dashes, numbers right-aligned by default; ``None`` in ``rows``
starts a new section (a rule between, e.g. before a mean line). Trailing spaces are
removed from every line.
"""

from __future__ import annotations

import io
import sys
from collections.abc import Iterable, Sequence

_RULES = ("    \n" "    \n" " -- \n" "    \n" " -- \n" " -- \n" "    \n" "    \n")
"""Only horizontal rules (under the header, between sections), in ASCII dashes; the
lines are top, head, head_row, mid, row, foot_row, foot, bottom (see rich.box). rich is
imported by :func:`render_table` alone: a name shown in a one-line error (:func:`visible`)
needs none of it."""


def render_table(
    header: Sequence[str],
    rows: Sequence[Sequence[str] | None],
    *,
    left: Iterable[int] = (),
    indent: int = 0,
    rule: bool = True,
) -> str:
    """``rows`` of cells under ``header`` (a header cell may hold several lines, e.g.
    name and unit) as text: columns whose index is in ``left`` left-aligned, the others
    right-aligned; each line indented by ``indent`` spaces; ``rule`` draws dashes under
    the header and between sections (``None`` rows)."""
    from rich import box
    from rich.console import Console
    from rich.table import Table

    left_set = set(left)
    table = Table(
        box=box.Box(_RULES, ascii=True) if rule else None,
        show_edge=False,
        pad_edge=False,
        padding=(0, 1 if rule else 2, 0, 0),  # with the box's blank divider: 2 spaces
        show_header=True,
        header_style="",
        highlight=False,
    )
    for index, name in enumerate(header):
        table.add_column(name, justify="left" if index in left_set else "right", no_wrap=True)
    for row in rows:
        if row is None:
            table.add_section()
        else:
            table.add_row(*row)
    buffer = io.StringIO()
    console = Console(file=buffer, width=10_000, color_system=None, force_terminal=False,
                      highlight=False, emoji=False, markup=False)
    console.print(table)
    lines = [" " * indent + line.rstrip() for line in buffer.getvalue().splitlines()]
    while lines and not lines[-1].strip():
        lines.pop()
    return "\n".join(line if line.strip() else "" for line in lines)


def visible(text: str, *, lines: bool = True, markup: bool = False) -> str:
    """``text`` safe to show, the one way every message and screen shows a name or text
    that came from a file or a folder (a card file's name, a session's note, a path):
    what it holds is shown, never obeyed. Every character that is not printable is
    written out (``\\x1b``, ``\\u202e``, ``\\udcff``): control characters (an escape
    sequence could redraw the screen, hide lines or retitle the window; a newline
    forge a line of a log), Unicode's invisible and direction-changing ones, and the
    bytes of a name that are not UTF-8 (which Python keeps as lone surrogates). Newline
    and tab are kept where ``lines`` (a note of several lines), written out where not
    (a name). ``markup``: for a screen that reads Rich/Textual markup, ``[`` escaped, so
    a name such as ``[a="b]x.png`` is shown as it is rather than read as a tag."""
    shown = "".join(c if c.isprintable() or (lines and c in "\n\t") else _written_out(c)
                    for c in text)
    return shown.replace("[", "\\[") if markup else shown


WARNINGS_SHOWN = 5
"""The most warnings of one kind :func:`warn` prints; the rest are counted."""


def warn(problems: Sequence[str], limit: int = WARNINGS_SHOWN) -> None:
    """Print ``problems`` to stderr as warnings, one line each and as many as ``limit``,
    then how many more there were: a log with 2,000 damaged rows says so in six lines,
    not 2,000."""
    for problem in problems[:limit]:
        print(f"warning: {visible(problem, lines=False)}", file=sys.stderr)
    if len(problems) > limit:
        print(f"warning: ... and {len(problems) - limit} more like these", file=sys.stderr)


def _written_out(char: str) -> str:
    code = ord(char)
    return f"\\x{code:02x}" if code < 0x100 else f"\\u{code:04x}" if code < 0x10000 \
        else f"\\U{code:08x}"
