"""The one table formatter: columns of text laid out by rich, rendered to plain text
(for files, logs, tests and terminals alike).

``render_table(header, rows)`` gives fixed-width columns two spaces apart under a
header and a rule of dashes, numbers right-aligned by default; ``None`` in ``rows``
starts a new section (a rule between, e.g. before a mean line). Trailing spaces are
removed from every line.
"""

from __future__ import annotations

import io
from collections.abc import Iterable, Sequence

from rich import box
from rich.console import Console
from rich.table import Table

#: Only horizontal rules (under the header, between sections), in ASCII dashes; the
#: lines are top, head, head_row, mid, row, foot_row, foot, bottom (see rich.box).
_RULES = box.Box(
    "    \n"
    "    \n"
    " -- \n"
    "    \n"
    " -- \n"
    " -- \n"
    "    \n"
    "    \n",
    ascii=True,
)


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
    left_set = set(left)
    table = Table(
        box=_RULES if rule else None,
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


_CONTROL = {c: f"\\x{c:02x}" for c in (*range(32), 127) if chr(c) not in "\n\t"}


def visible(text: str) -> str:
    """``text`` with every control character but newline and tab written out as
    ``\\xNN``: what a session from someone else holds (a note, an operator's name) is
    shown, not obeyed by the terminal (an escape sequence could redraw the screen,
    hide lines or retitle the window)."""
    return text.translate(_CONTROL)
