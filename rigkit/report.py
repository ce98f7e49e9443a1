"""Summaries, tables and plots of the rangefinder-vs-estimate logs of capture sessions.

:func:`collect` reads the ``comparisons.csv`` log of each session folder (by default only
each session's newest run), :func:`summarize` computes error statistics overall and per
laser-range bucket, :func:`format_text` and :func:`write_csv` give the table, and
:func:`plot_estimate_vs_laser` and :func:`plot_error_vs_range` draw the two plots as BGR
images with OpenCV (write them with :func:`rigkit.core.files.write_png`).

Sign convention (as in :mod:`rigkit.capture.comparisons`): ``error = estimate - laser``; a
positive error puts the target too far. Percentages are of the laser range. Statistics
use the usable (``ok``) rows only; the others are counted by status.
"""

from __future__ import annotations

import math
import statistics
from collections import Counter
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from rigkit.capture.comparisons import (
    LOG_NAME,
    STATUS_OK,
    Comparison,
    csv_text,
    latest_run,
    read_rows,
)
from rigkit.errors import InputError

#: Bucket edges by laser range, metres: <100, 100-200, ..., 400-500, >=500.
DEFAULT_EDGES_M: tuple[float, ...] = (100.0, 200.0, 300.0, 400.0, 500.0)
#: The two tolerance bands of the report, percent of the laser range.
TIGHT_PCT = 1.0
LOOSE_PCT = 3.0
_EPS_PCT = 1e-9  # a value logged as exactly 1 % counts as within 1 %


# --------------------------------------------------------------------------- reading


def collect(session_dirs: Iterable[Path], all_runs: bool = False) -> list[Comparison]:
    """The comparison rows of the given session folders, in the order given.

    Each folder must hold ``comparisons.csv`` at its top level. By default only each
    session's newest run is kept; ``all_runs`` keeps every run. A folder given twice is
    read once. InputError (naming the folder or file) for a missing folder, a folder
    without a log, or a malformed log.
    """
    rows: list[Comparison] = []
    seen: set[Path] = set()
    for folder in session_dirs:
        folder = Path(folder)
        key = folder.resolve()
        if key in seen:
            continue
        seen.add(key)
        rows.extend(_session_rows(folder, all_runs))
    return rows


def _session_rows(folder: Path, all_runs: bool) -> list[Comparison]:
    if not folder.exists():
        raise InputError(f"{folder}: no such session folder")
    if not folder.is_dir():
        raise InputError(f"{folder}: not a session folder (give the folder that holds {LOG_NAME})")
    rows = read_rows(folder / LOG_NAME)
    return rows if all_runs else latest_run(rows)


# --------------------------------------------------------------------------- statistics


@dataclass(frozen=True)
class Stats:
    """Error statistics of a group of comparisons.

    ``total`` counts every row, ``ok`` the usable ones (status ``ok`` with a finite
    error), ``failed`` the others by status. The error figures are over the ok rows, in
    percent of the laser range (NaN when there are none); ``within_1`` / ``within_3`` are
    the shares (0-1) of ok rows with ``|error| <= 1 %`` / ``<= 3 %``; ``outliers`` counts
    ok rows beyond 3 %.
    """

    total: int
    ok: int
    failed: dict[str, int]
    mean_abs_pct: float
    median_abs_pct: float
    max_abs_pct: float
    bias_pct: float
    within_1: float
    within_3: float
    outliers: int


@dataclass(frozen=True)
class Bucket:
    """The rows whose laser range is in ``[lo_m, hi_m)`` (either end may be infinite)."""

    lo_m: float
    hi_m: float
    stats: Stats

    @property
    def label(self) -> str:
        if math.isinf(self.lo_m):
            return f"<{self.hi_m:g}"
        if math.isinf(self.hi_m):
            return f">={self.lo_m:g}"
        return f"{self.lo_m:g}-{self.hi_m:g}"


@dataclass(frozen=True)
class Summary:
    """Statistics of all rows and per laser-range bucket (rows without a laser range are
    in ``overall`` but in no bucket; empty buckets are kept, with ``total == 0``)."""

    overall: Stats
    buckets: tuple[Bucket, ...]


def is_outlier(row: Comparison, limit_pct: float = LOOSE_PCT) -> bool:
    """A usable row whose error is beyond ``limit_pct`` percent."""
    return row.ok and abs(row.error_pct) > limit_pct + _EPS_PCT


def stats(rows: Sequence[Comparison]) -> Stats:
    """Counts and error statistics of ``rows`` (see :class:`Stats`)."""
    errors = [row.error_pct for row in rows if row.ok]
    failed = Counter(_failure(row) for row in rows if not row.ok)
    nan = math.nan
    abs_errors = [abs(e) for e in errors]
    return Stats(
        total=len(rows),
        ok=len(errors),
        failed=dict(sorted(failed.items())),
        mean_abs_pct=statistics.fmean(abs_errors) if errors else nan,
        median_abs_pct=statistics.median(abs_errors) if errors else nan,
        max_abs_pct=max(abs_errors) if errors else nan,
        bias_pct=statistics.fmean(errors) if errors else nan,
        within_1=_share(abs_errors, TIGHT_PCT),
        within_3=_share(abs_errors, LOOSE_PCT),
        outliers=sum(1 for e in abs_errors if e > LOOSE_PCT + _EPS_PCT),
    )


def _failure(row: Comparison) -> str:
    # Status "ok" without a finite error should not happen; keep it visible if it does.
    return row.status if row.status != STATUS_OK else "ok_without_error"


def _share(abs_errors: Sequence[float], limit_pct: float) -> float:
    if not abs_errors:
        return math.nan
    return sum(1 for e in abs_errors if e <= limit_pct + _EPS_PCT) / len(abs_errors)


def summarize(rows: Sequence[Comparison], edges_m: Sequence[float] = DEFAULT_EDGES_M) -> Summary:
    """Statistics of ``rows`` overall and per bucket of laser range.

    ``edges_m`` (increasing, metres) split the range axis into ``len(edges_m) + 1``
    buckets ``[-inf, e0), [e0, e1), ..., [e_last, inf)``.
    """
    edges = [float(e) for e in edges_m]
    if any(b <= a for a, b in zip(edges, edges[1:], strict=False)) or not all(
        math.isfinite(e) for e in edges
    ):
        raise ValueError(f"bucket edges must be finite and increasing, got {list(edges_m)}")
    bounds = [-math.inf, *edges, math.inf]
    buckets = tuple(
        Bucket(lo, hi, stats([r for r in rows if lo <= r.laser_range_m < hi]))
        for lo, hi in zip(bounds, bounds[1:], strict=False)
    )
    return Summary(overall=stats(rows), buckets=buckets)


# --------------------------------------------------------------------------- text and CSV


def _num(value: float, spec: str) -> str:
    return "-" if not math.isfinite(value) else format(value, spec)


def _share_text(share: float, n: int) -> str:
    if not math.isfinite(share):
        return "-"
    return f"{round(share * n)}/{n}"


def _table(header: Sequence[str], lines: Sequence[Sequence[str]], left: Iterable[int]) -> list[str]:
    """Fixed-width columns: those whose index is in ``left`` left-aligned, the rest right."""
    left_set = set(left)
    widths = [max(len(h), *(len(line[i]) for line in lines)) for i, h in enumerate(header)]

    def fmt(cells: Sequence[str]) -> str:
        parts = [
            c.ljust(w) if i in left_set else c.rjust(w)
            for i, (c, w) in enumerate(zip(cells, widths, strict=True))
        ]
        return "  ".join(parts).rstrip()

    head = fmt(header)
    return [head, "-" * len(head), *(fmt(line) for line in lines)]


def _several_runs(rows: Sequence[Comparison]) -> bool:
    runs: dict[str, set[str]] = {}
    for row in rows:
        runs.setdefault(row.session, set()).add(row.run_id)
    return any(len(ids) > 1 for ids in runs.values())


def format_rows(rows: Sequence[Comparison]) -> str:
    """One line per comparison; a run column appears when a session has several runs."""
    with_run = _several_runs(rows)
    header = ["session", *(["run"] if with_run else []), "target"]
    left = len(header)
    header += ["laser m", "estimate m", "error m", "error %", "sigma m", "status"]
    lines = []
    for r in rows:
        status = r.status + (f" (>{LOOSE_PCT:g} %)" if is_outlier(r) else "")
        lines.append(
            [
                r.session,
                *([r.run_id] if with_run else []),
                r.target,
                _num(r.laser_range_m, ".2f"),
                _num(r.estimate_range_m, ".2f"),
                _num(r.error_m, "+.2f"),
                _num(r.error_pct, "+.3f"),
                _num(r.estimate_sigma_m, ".2f"),
                status,
            ]
        )
    if not lines:
        return "no comparisons"
    return "\n".join(_table(header, lines, [*range(left), len(header) - 1]))


def _failed_text(s: Stats) -> str:
    if not s.failed:
        return "0 failed"
    parts = ", ".join(f"{k} {v}" for k, v in s.failed.items())
    return f"{s.total - s.ok} failed ({parts})"


def format_stats(s: Stats) -> str:
    """The overall statistics as a few indented lines."""
    lines = [f"{s.total} comparisons: {s.ok} ok, {_failed_text(s)}"]
    if s.ok:
        lines += [
            f"  |error|: mean {s.mean_abs_pct:.3f} %, median {s.median_abs_pct:.3f} %, "
            f"max {s.max_abs_pct:.3f} %",
            f"  bias (mean signed error, estimate - laser): {s.bias_pct:+.3f} %",
            f"  within {TIGHT_PCT:g} %: {_share_text(s.within_1, s.ok)} "
            f"({100 * s.within_1:.1f} %), within {LOOSE_PCT:g} %: "
            f"{_share_text(s.within_3, s.ok)} ({100 * s.within_3:.1f} %)",
            f"  outliers beyond {LOOSE_PCT:g} %: {s.outliers}",
        ]
    return "\n".join(lines)


def format_buckets(buckets: Sequence[Bucket]) -> str:
    """One line per non-empty bucket."""
    header = ["laser range m", "n", "ok", "mean|e| %", "median|e| %", "max|e| %", "bias %"]
    header += [f"<={TIGHT_PCT:g} %", f"<={LOOSE_PCT:g} %"]
    lines = []
    for b in buckets:
        s = b.stats
        if s.total == 0:
            continue
        lines.append(
            [
                b.label,
                str(s.total),
                str(s.ok),
                _num(s.mean_abs_pct, ".3f"),
                _num(s.median_abs_pct, ".3f"),
                _num(s.max_abs_pct, ".3f"),
                _num(s.bias_pct, "+.3f"),
                _share_text(s.within_1, s.ok),
                _share_text(s.within_3, s.ok),
            ]
        )
    if not lines:
        return "no comparisons with a laser range"
    return "\n".join(_table(header, lines, left=[0]))


def _outlier_lines(rows: Sequence[Comparison]) -> list[str]:
    """The usable rows beyond 3 %, worst first, as one indented line each."""
    worst = sorted((r for r in rows if is_outlier(r)), key=lambda r: -abs(r.error_pct))
    return [
        f"    {r.session}/{r.target}: {r.error_pct:+.3f} % ({r.error_m:+.2f} m at "
        f"{r.laser_range_m:.2f} m)"
        for r in worst
    ]


def format_text(rows: Sequence[Comparison], summary: Summary) -> str:
    """The full text report: every comparison, the summary, and the per-bucket table."""
    sessions = list(dict.fromkeys(r.session for r in rows))
    parts = [
        f"rangefinder comparisons: {len(rows)} rows from {len(sessions)} session(s)"
        + (f" ({', '.join(sessions)})" if sessions else ""),
        "error = estimate - laser (positive: estimate too far); % of the laser range",
        "",
        format_rows(rows),
        "",
        "summary",
        format_stats(summary.overall),
        *_outlier_lines(rows),
        "",
        "by laser range",
        format_buckets(summary.buckets),
    ]
    return "\n".join(parts) + "\n"


def write_csv(path: Path, rows: Sequence[Comparison]) -> None:
    """The rows as CSV with the log's columns (readable again by ``read_rows``)."""
    path.write_text(csv_text(rows), encoding="utf-8")


# --------------------------------------------------------------------------- plotting

Colour = tuple[int, int, int]  # BGR

WHITE: Colour = (255, 255, 255)
INK: Colour = (40, 40, 40)
GREY: Colour = (110, 110, 110)
GRID: Colour = (228, 228, 228)
OUTLIER: Colour = (20, 20, 215)
BAND_TIGHT: Colour = (40, 150, 40)  # the 1 % band: lines, and its fill below
BAND_LOOSE: Colour = (0, 140, 245)  # the 3 % band
FILL_TIGHT: Colour = (190, 232, 190)
FILL_LOOSE: Colour = (205, 232, 255)
#: Point colours by session (the "tab10" palette, BGR).
PALETTE: tuple[Colour, ...] = (
    (180, 119, 31),
    (14, 127, 255),
    (44, 160, 44),
    (189, 103, 148),
    (75, 86, 140),
    (194, 119, 227),
    (127, 127, 127),
    (34, 189, 188),
    (207, 190, 23),
)

FONT = cv2.FONT_HERSHEY_SIMPLEX
TITLE_SCALE, LABEL_SCALE, TICK_SCALE, NOTE_SCALE = 0.8, 0.6, 0.5, 0.5
MARKER_R = 5
PLOT_SIZE = (1000, 700)  # width, height, px
MAX_ERROR_AXIS_PCT = 10.0  # plot_error_vs_range clips its y axis here; beyond: arrows


def nice_ticks(lo: float, hi: float, target: int = 6) -> tuple[float, float, list[float]]:
    """An axis span covering ``[lo, hi]`` with about ``target`` ticks on a 1-2-5 step.

    Returns ``(axis_lo, axis_hi, ticks)``; the axis ends are multiples of the step. A
    zero or non-finite span is widened first so that the axis never collapses.
    """
    lo, hi = _widen(lo, hi)
    raw = (hi - lo) / max(target - 1, 1)
    power = 10.0 ** math.floor(math.log10(raw))
    step = next(m * power for m in (1, 2, 5, 10) if m * power >= raw * (1 - 1e-9))
    first, last = math.floor(lo / step + 1e-9), math.ceil(hi / step - 1e-9)
    ticks = [round(i * step, 12) for i in range(first, last + 1)]
    return ticks[0], ticks[-1], ticks


def _widen(lo: float, hi: float) -> tuple[float, float]:
    if not (math.isfinite(lo) and math.isfinite(hi)):
        return 0.0, 1.0
    lo, hi = min(lo, hi), max(lo, hi)
    if hi - lo < 1e-9 * max(1.0, abs(lo), abs(hi)):
        pad = max(1.0, 0.05 * abs(lo))
        return lo - pad, hi + pad
    return lo, hi


def tick_label(value: float, ticks: Sequence[float], signed: bool = False) -> str:
    """``value`` with as many decimals as the tick step needs."""
    step = abs(ticks[1] - ticks[0]) if len(ticks) > 1 else 1.0
    decimals = max(0, -math.floor(math.log10(step) + 1e-9))
    if abs(value) < step * 1e-6:
        value = 0.0
    text = f"{value:.{decimals}f}"
    return f"+{text}" if signed and value > 0 else text


def _text(
    img: np.ndarray,
    text: str,
    org: tuple[float, float],
    scale: float = TICK_SCALE,
    colour: Colour = INK,
    thickness: int = 1,
    align: str = "left",
    valign: str = "baseline",
) -> None:
    """Anti-aliased text; ``align`` left/center/right, ``valign`` baseline/center/top."""
    (w, h), _ = cv2.getTextSize(text, FONT, scale, thickness)
    x = org[0] - {"left": 0, "center": w / 2, "right": w}[align]
    y = org[1] + {"baseline": 0, "center": h / 2, "top": h}[valign]
    cv2.putText(img, text, (round(x), round(y)), FONT, scale, colour, thickness, cv2.LINE_AA)


def _text_width(text: str, scale: float, thickness: int = 1) -> int:
    return int(cv2.getTextSize(text, FONT, scale, thickness)[0][0])


def _vertical_text(img: np.ndarray, text: str, centre: tuple[int, int], scale: float) -> None:
    """Text rotated 90 degrees counter-clockwise (a y-axis label) centred at ``centre``."""
    (w, h), base = cv2.getTextSize(text, FONT, scale, 1)
    patch: np.ndarray = np.full((h + base + 4, w + 4, 3), 255, np.uint8)
    cv2.putText(patch, text, (2, h + 2), FONT, scale, INK, 1, cv2.LINE_AA)
    patch = cv2.rotate(patch, cv2.ROTATE_90_COUNTERCLOCKWISE)
    ph, pw = patch.shape[:2]
    x0, y0 = centre[0] - pw // 2, centre[1] - ph // 2
    img[y0 : y0 + ph, x0 : x0 + pw] = np.minimum(img[y0 : y0 + ph, x0 : x0 + pw], patch)


def _dashed(
    img: np.ndarray, p: tuple[int, int], q: tuple[int, int], colour: Colour, dash: int = 9
) -> None:
    """A dashed line from ``p`` to ``q`` (dash and gap ``dash`` px)."""
    length = math.hypot(q[0] - p[0], q[1] - p[1])
    n = max(1, int(length // dash))
    for i in range(0, n, 2):
        a, b = i / n, min(i + 1, n) / n
        s = (round(p[0] + a * (q[0] - p[0])), round(p[1] + a * (q[1] - p[1])))
        e = (round(p[0] + b * (q[0] - p[0])), round(p[1] + b * (q[1] - p[1])))
        cv2.line(img, s, e, colour, 1, cv2.LINE_AA)


@dataclass(frozen=True)
class LegendItem:
    """One legend entry; ``kind`` is ``point``, ``ring``, ``line``, ``dashed`` or ``fill``."""

    label: str
    kind: str
    colour: Colour
    edge: Colour | None = None


def _legend_rows(items: Sequence[LegendItem], width: int) -> list[list[LegendItem]]:
    rows: list[list[LegendItem]] = [[]]
    used = 0
    for item in items:
        w = 30 + _text_width(item.label, NOTE_SCALE) + 24
        if rows[-1] and used + w > width:
            rows.append([])
            used = 0
        rows[-1].append(item)
        used += w
    return rows


def _legend_swatch(img: np.ndarray, item: LegendItem, x: int, y: int) -> None:
    """The item's symbol in a 24 px wide cell whose vertical centre is ``y``."""
    if item.kind == "fill":
        cv2.rectangle(img, (x, y - 7), (x + 24, y + 7), item.colour, -1)
        cv2.rectangle(img, (x, y - 7), (x + 24, y + 7), item.edge or item.colour, 1)
    elif item.kind == "line":
        cv2.line(img, (x, y), (x + 24, y), item.colour, 2, cv2.LINE_AA)
    elif item.kind == "dashed":
        _dashed(img, (x, y), (x + 24, y), item.colour, dash=5)
    elif item.kind == "ring":
        cv2.circle(img, (x + 12, y), MARKER_R + 4, item.colour, 2, cv2.LINE_AA)
    else:
        _marker(img, (x + 12, y), item.colour)


def _draw_legend(img: np.ndarray, items: Sequence[LegendItem], x0: int, y0: int, width: int) -> int:
    """Legend entries in rows from ``(x0, y0)``; returns the y just below the legend."""
    y = y0
    for row in _legend_rows(items, width):
        x = x0
        for item in row:
            _legend_swatch(img, item, x, y + 10)
            _text(img, item.label, (x + 30, y + 10), NOTE_SCALE, INK, valign="center")
            x += 30 + _text_width(item.label, NOTE_SCALE) + 24
        y += 24
    return y


def _marker(img: np.ndarray, centre: tuple[int, int], colour: Colour) -> None:
    cv2.circle(img, centre, MARKER_R, colour, -1, cv2.LINE_AA)
    cv2.circle(img, centre, MARKER_R, INK, 1, cv2.LINE_AA)


@dataclass(frozen=True)
class Axes:
    """A plot area in an image and the data ranges it shows (pixel y grows downwards)."""

    left: int
    top: int
    right: int
    bottom: int
    xlim: tuple[float, float]
    ylim: tuple[float, float]

    def px(self, x: float, y: float) -> tuple[int, int]:
        """Data coordinates to pixel coordinates (not clipped)."""
        fx = (x - self.xlim[0]) / (self.xlim[1] - self.xlim[0])
        fy = (y - self.ylim[0]) / (self.ylim[1] - self.ylim[0])
        return round(self.left + fx * (self.right - self.left)), round(
            self.bottom - fy * (self.bottom - self.top)
        )

    def polygon(self, points: Sequence[tuple[float, float]]) -> np.ndarray:
        return np.array([self.px(x, y) for x, y in points], np.int32)


def _canvas(size: tuple[int, int]) -> np.ndarray:
    return np.full((size[1], size[0], 3), 255, np.uint8)


def _header(img: np.ndarray, title: str, subtitle: str) -> int:
    """Title and subtitle at the top; returns the y below them."""
    w = img.shape[1]
    _text(img, title, (w / 2, 34), TITLE_SCALE, INK, 2, align="center")
    _text(img, subtitle, (w / 2, 60), NOTE_SCALE, GREY, align="center")
    return 74


def _layout(img: np.ndarray, legend: Sequence[LegendItem], top: int) -> tuple[int, int, int, int]:
    """Draw the legend under the header; returns the plot area (left, top, right, bottom)."""
    h, w = img.shape[:2]
    left, right, bottom = 96, w - 36, h - 70
    below = _draw_legend(img, legend, left, top, right - left)
    return left, below + 12, right, bottom


def _frame(
    img: np.ndarray,
    ax: Axes,
    xticks: Sequence[float],
    yticks: Sequence[float],
    xlabel: str,
    ylabel: str,
    signed_y: bool = False,
) -> None:
    """Grid, tick labels, axis labels (drawn before the data)."""
    for t in xticks:
        x, _ = ax.px(t, 0)
        cv2.line(img, (x, ax.top), (x, ax.bottom), GRID, 1)
        cv2.line(img, (x, ax.bottom), (x, ax.bottom + 5), INK, 1)
        _text(
            img,
            tick_label(t, xticks),
            (x, ax.bottom + 10),
            TICK_SCALE,
            align="center",
            valign="top",
        )
    for t in yticks:
        _, y = ax.px(0, t)
        cv2.line(img, (ax.left, y), (ax.right, y), GRID, 1)
        cv2.line(img, (ax.left - 5, y), (ax.left, y), INK, 1)
        label = tick_label(t, yticks, signed_y)
        _text(img, label, (ax.left - 9, y), TICK_SCALE, align="right", valign="center")
    _text(img, xlabel, ((ax.left + ax.right) / 2, ax.bottom + 52), LABEL_SCALE, align="center")
    _vertical_text(img, ylabel, (26, (ax.top + ax.bottom) // 2), LABEL_SCALE)


def _border(img: np.ndarray, ax: Axes) -> None:
    cv2.rectangle(img, (ax.left, ax.top), (ax.right, ax.bottom), INK, 1)


def _fill_clipped(img: np.ndarray, ax: Axes, polygon: np.ndarray, colour: Colour) -> None:
    """Fill ``polygon``, clipped to the plot area (opaque: the bands are drawn first)."""
    layer = img.copy()
    cv2.fillPoly(layer, [polygon], colour, cv2.LINE_AA)
    sl = np.s_[ax.top : ax.bottom + 1, ax.left : ax.right + 1]
    img[sl] = layer[sl]


def _clipped(img: np.ndarray, ax: Axes, draw: Callable[[np.ndarray], None]) -> None:
    """Run ``draw`` on a copy and keep only what lands inside the plot area."""
    layer = img.copy()
    draw(layer)
    sl = np.s_[ax.top + 1 : ax.bottom, ax.left + 1 : ax.right]
    img[sl] = layer[sl]


def _usable(rows: Sequence[Comparison]) -> list[Comparison]:
    return [
        r
        for r in rows
        if r.ok and math.isfinite(r.laser_range_m) and math.isfinite(r.estimate_range_m)
    ]


def _colours(rows: Sequence[Comparison]) -> dict[str, Colour]:
    sessions = list(dict.fromkeys(r.session for r in rows))
    return {s: PALETTE[i % len(PALETTE)] for i, s in enumerate(sessions)}


def _subtitle(rows: Sequence[Comparison], shown: int) -> str:
    sessions = len({r.session for r in rows})
    text = f"{shown} comparison{'s' if shown != 1 else ''} from {sessions} session"
    text += "s" if sessions != 1 else ""
    hidden = len(rows) - shown
    if hidden:
        text += f"; {hidden} without an estimate or laser reading not shown"
    return text


def _session_legend(rows: Sequence[Comparison], colours: dict[str, Colour]) -> list[LegendItem]:
    counts = Counter(r.session for r in rows)
    items = [LegendItem(f"{s} ({counts[s]})", "point", c) for s, c in colours.items()]
    if any(is_outlier(r) for r in rows):
        items.append(LegendItem(f"beyond {LOOSE_PCT:g} %", "ring", OUTLIER))
    return items


def _band_legend(centre: str) -> list[LegendItem]:
    return [
        LegendItem(centre, "line", INK),
        LegendItem(f"+/-{TIGHT_PCT:g} %", "fill", FILL_TIGHT, BAND_TIGHT),
        LegendItem(f"+/-{LOOSE_PCT:g} %", "fill", FILL_LOOSE, BAND_LOOSE),
    ]


def _empty_plot(size: tuple[int, int], title: str, xlabel: str, ylabel: str) -> np.ndarray:
    img = _canvas(size)
    top = _header(img, title, "no comparisons")
    left, top, right, bottom = _layout(img, [], top)
    ax = Axes(left, top, right, bottom, (0.0, 1.0), (0.0, 1.0))
    _frame(img, ax, [], [], xlabel, ylabel)
    _border(img, ax)
    _text(
        img,
        "no comparisons",
        ((left + right) / 2, (top + bottom) / 2),
        TITLE_SCALE,
        GREY,
        2,
        align="center",
        valign="center",
    )
    return img


def _point(
    img: np.ndarray,
    ax: Axes,
    x: float,
    y: float,
    sigma: float,
    colour: Colour,
    outlier: bool,
) -> tuple[int, int]:
    """A marker with a vertical one-sigma error bar (when it is longer than the marker)."""
    cx, cy = ax.px(x, y)
    if math.isfinite(sigma) and sigma > 0:
        _, top = ax.px(x, y + sigma)
        _, bottom = ax.px(x, y - sigma)
        if bottom - top > 2 * MARKER_R + 2:
            cv2.line(img, (cx, top), (cx, bottom), GREY, 1, cv2.LINE_AA)
            cv2.line(img, (cx - 4, top), (cx + 4, top), GREY, 1, cv2.LINE_AA)
            cv2.line(img, (cx - 4, bottom), (cx + 4, bottom), GREY, 1, cv2.LINE_AA)
    _marker(img, (cx, cy), colour)
    if outlier:
        cv2.circle(img, (cx, cy), MARKER_R + 4, OUTLIER, 2, cv2.LINE_AA)
    return cx, cy


def _point_label(
    img: np.ndarray,
    ax: Axes,
    at: tuple[int, int],
    text: str,
    above: bool = True,
    left: bool = False,
) -> None:
    """Label an outlier diagonally beside its marker in a white box, inside the plot area.

    ``above`` / ``left`` choose the side (away from the other points), flipped
    horizontally where the label would leave the plot area.
    """
    (tw, th), base = cv2.getTextSize(text, FONT, NOTE_SCALE, 1)
    gap = MARKER_R + 7
    x = at[0] - gap - tw if left else at[0] + gap
    if x + tw > ax.right - 6:
        x = at[0] - gap - tw
    if x < ax.left + 6:
        x = at[0] + gap
    y = at[1] - gap if above else at[1] + gap + th
    y = min(max(y, ax.top + th + 8), ax.bottom - base - 6)
    cv2.rectangle(img, (x - 3, y - th - 3), (x + tw + 3, y + base), WHITE, -1)
    cv2.rectangle(img, (x - 3, y - th - 3), (x + tw + 3, y + base), OUTLIER, 1)
    _text(img, text, (x, y), NOTE_SCALE, OUTLIER)


def plot_estimate_vs_laser(
    rows: Sequence[Comparison], size: tuple[int, int] = PLOT_SIZE
) -> np.ndarray:
    """Scatter of estimated range against laser range (BGR uint8 image, ``size`` = (w, h)).

    Shows the line estimate = laser and the 1 % and 3 % bands around it, one-sigma error
    bars where they are longer than a marker, points coloured by session and the rows
    beyond 3 % ringed in red and labelled. Rows that are not ok are left out (counted in
    the subtitle). Both axes show the same span, in metres.
    """
    title = "Estimated range vs laser range"
    xlabel, ylabel = "laser range (m)", "estimated range (m)"
    usable = _usable(rows)
    if not usable:
        return _empty_plot(size, title, xlabel, ylabel)
    img = _canvas(size)
    colours = _colours(usable)
    legend = _session_legend(usable, colours) + _band_legend("estimate = laser")
    left, top, right, bottom = _layout(
        img, legend, _header(img, title, _subtitle(rows, len(usable)))
    )
    a, b, ticks = _range_axis(usable)
    ax = Axes(left, top, right, bottom, (a, b), (a, b))
    _frame(img, ax, ticks, ticks, xlabel, ylabel)
    for pct, fill in ((LOOSE_PCT, FILL_LOOSE), (TIGHT_PCT, FILL_TIGHT)):
        k = pct / 100
        band = ax.polygon([(a, a * (1 - k)), (b, b * (1 - k)), (b, b * (1 + k)), (a, a * (1 + k))])
        _fill_clipped(img, ax, band, fill)
    _clipped(img, ax, lambda layer: _ratio_lines(layer, ax, a, b))
    _scatter(
        img,
        ax,
        usable,
        colours,
        lambda r: (r.laser_range_m, r.estimate_range_m, r.estimate_sigma_m),
        diagonal=True,
    )
    _border(img, ax)
    return img


def _range_axis(rows: Sequence[Comparison]) -> tuple[float, float, list[float]]:
    """The common x and y axis of the estimate-vs-laser plot: all ranges plus a margin,
    and at least 4 x the 3 % band's half-width so that a few close points still show
    the bands."""
    values = [r.laser_range_m for r in rows] + [r.estimate_range_m for r in rows]
    lo, hi = _widen(min(values), max(values))
    pad = 0.05 * (hi - lo)
    lo, hi = lo - pad, hi + pad
    min_span = 4 * LOOSE_PCT / 100 * max(abs(lo), abs(hi))
    if hi - lo < min_span:
        mid = (lo + hi) / 2
        lo, hi = mid - min_span / 2, mid + min_span / 2
    return nice_ticks(lo, hi)


def _ratio_lines(img: np.ndarray, ax: Axes, a: float, b: float) -> None:
    """y = x solid and y = x (1 +/- k) dashed for both bands."""
    for pct, colour in ((LOOSE_PCT, BAND_LOOSE), (TIGHT_PCT, BAND_TIGHT)):
        for sign in (-1, 1):
            k = 1 + sign * pct / 100
            _dashed(img, ax.px(a, a * k), ax.px(b, b * k), colour)
    cv2.line(img, ax.px(a, a), ax.px(b, b), INK, 2, cv2.LINE_AA)


def _scatter(
    img: np.ndarray,
    ax: Axes,
    rows: Sequence[Comparison],
    colours: dict[str, Colour],
    xys: Callable[[Comparison], tuple[float, float, float]],
    diagonal: bool = False,
) -> None:
    """Markers (ok points first, so outliers and their labels stay on top).

    Outlier labels go above the point for a positive error and below for a negative one;
    with ``diagonal`` (points along y = x) also left or right, away from the diagonal.
    """
    ordered = sorted(rows, key=is_outlier)
    labels = []
    for r in ordered:
        x, y, s = xys(r)
        at = _point(img, ax, x, y, s, colours[r.session], is_outlier(r))
        if is_outlier(r):
            labels.append((at, f"{r.target} {r.error_pct:+.1f} %", r.error_pct > 0))
    for at, text, above in labels:
        _point_label(img, ax, at, text, above=above, left=above and diagonal)


def plot_error_vs_range(
    rows: Sequence[Comparison],
    size: tuple[int, int] = PLOT_SIZE,
    max_axis_pct: float = MAX_ERROR_AXIS_PCT,
) -> np.ndarray:
    """Signed error (% of laser range) against laser range (BGR uint8 image).

    A zero line, the +/-1 % and +/-3 % bands, one-sigma error bars (in % of the range)
    where longer than a marker, points coloured by session, rows beyond 3 % ringed in red
    and labelled. The y axis is symmetric, at least +/-4 % and at most ``max_axis_pct``;
    errors beyond it are drawn as arrows at the edge. Rows that are not ok are left out.
    """
    title = "Range error vs laser range"
    xlabel = "laser range (m)"
    ylabel = "error, estimate - laser (% of laser range)"
    usable = _usable(rows)
    if not usable:
        return _empty_plot(size, title, xlabel, ylabel)
    xa, xb, xticks = _laser_axis(usable)
    ya, yb, yticks = _error_axis(usable, max_axis_pct)
    inside = [r for r in usable if ya <= r.error_pct <= yb]
    outside = [r for r in usable if not ya <= r.error_pct <= yb]
    subtitle = _subtitle(rows, len(usable))
    if outside:
        subtitle += f"; {len(outside)} beyond the axis drawn as arrows"
    img = _canvas(size)
    colours = _colours(usable)
    legend = _session_legend(usable, colours) + _band_legend("zero error")
    left, top, right, bottom = _layout(img, legend, _header(img, title, subtitle))
    ax = Axes(left, top, right, bottom, (xa, xb), (ya, yb))
    _frame(img, ax, xticks, yticks, xlabel, ylabel, signed_y=True)
    _error_bands(img, ax)
    _scatter(img, ax, inside, colours, _error_xys)
    for r in outside:
        _off_scale(img, ax, r, colours[r.session])
    _border(img, ax)
    return img


def _laser_axis(rows: Sequence[Comparison]) -> tuple[float, float, list[float]]:
    """Laser ranges plus a 5 % margin each side."""
    ranges = [r.laser_range_m for r in rows]
    lo, hi = _widen(min(ranges), max(ranges))
    pad = 0.05 * (hi - lo)
    return nice_ticks(lo - pad, hi + pad)


def _error_axis(
    rows: Sequence[Comparison], max_axis_pct: float
) -> tuple[float, float, list[float]]:
    """Symmetric: the largest error plus 15 %, at least 4 % (the 3 % band shows), at most
    ``max_axis_pct``."""
    floor = LOOSE_PCT + 1
    worst = max(abs(r.error_pct) for r in rows)
    span = min(max(floor, 1.15 * worst), max(max_axis_pct, floor))
    return nice_ticks(-span, span, target=7)


def _error_xys(r: Comparison) -> tuple[float, float, float]:
    return r.laser_range_m, r.error_pct, 100 * r.estimate_sigma_m / r.laser_range_m


def _error_bands(img: np.ndarray, ax: Axes) -> None:
    (xa, xb) = ax.xlim
    for pct, fill in ((LOOSE_PCT, FILL_LOOSE), (TIGHT_PCT, FILL_TIGHT)):
        _fill_clipped(img, ax, ax.polygon([(xa, -pct), (xb, -pct), (xb, pct), (xa, pct)]), fill)
    for pct, colour in ((LOOSE_PCT, BAND_LOOSE), (TIGHT_PCT, BAND_TIGHT)):
        for sign in (-1, 1):
            _dashed(img, ax.px(xa, sign * pct), ax.px(xb, sign * pct), colour)
    cv2.line(img, ax.px(xa, 0), ax.px(xb, 0), INK, 2, cv2.LINE_AA)


def _off_scale(img: np.ndarray, ax: Axes, r: Comparison, colour: Colour) -> None:
    """An arrow at the top or bottom edge for an error beyond the y axis, labelled."""
    up = r.error_pct > ax.ylim[1]
    x, _ = ax.px(r.laser_range_m, 0)
    tip = ax.top + 4 if up else ax.bottom - 4
    base = tip + 16 if up else tip - 16
    tri = np.array([(x, tip), (x - 7, base), (x + 7, base)], np.int32)
    cv2.fillPoly(img, [tri], colour, cv2.LINE_AA)
    cv2.polylines(img, [tri], True, OUTLIER, 2, cv2.LINE_AA)
    text = f"{r.target} {r.error_pct:+.1f} %"
    _point_label(img, ax, (x + 4, (tip + base) // 2), text, above=up)
