"""The report's two plots, drawn with matplotlib (Agg, no display needed).

:func:`plot_estimate_vs_laser`: estimated range against laser range, with the line
estimate = laser and the 1 % and 3 % bands around it. :func:`plot_error_vs_range`:
the signed error in % of the laser range against the laser range, with the zero line
and the same bands; errors beyond its y axis are drawn as triangles at the edge.
Both show one-sigma error bars, colour points by session, and ring and label the rows
beyond 3 % in red. Rows that are not ``ok`` are left out and counted in the subtitle.

Each returns a :class:`matplotlib.figure.Figure` of ``size`` pixels; :func:`render`
turns it into PNG, SVG or PDF bytes. The artists carry ids (``gid``) naming what they
show (``points:<session>``, ``outliers``, ``off-scale``, ``centre-line``, ``band-1``,
``band-3``), so tests can check a plot's content without reading pixels.
"""

from __future__ import annotations

import io
import math
from collections import Counter
from collections.abc import Callable, Sequence

from matplotlib import rc_context
from matplotlib.axes import Axes
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from matplotlib.ticker import MaxNLocator

from rigkit.capture.comparisons import Comparison
from rigkit.reporting.summary import LOOSE_PCT, TIGHT_PCT, is_outlier

#: Formats :func:`render` writes (``rigkit report --format``).
FORMATS = ("png", "svg", "pdf")
PLOT_SIZE = (1000, 700)  # width, height, px
DPI = 100
MAX_ERROR_AXIS_PCT = 10.0  # plot_error_vs_range clips its y axis here; beyond: triangles

INK = "#282828"
GREY = "#6e6e6e"
OUTLIER = "#d71414"
BAND_TIGHT, FILL_TIGHT = "#289628", "#bee8be"  # the 1 % band: lines, and its fill
BAND_LOOSE, FILL_LOOSE = "#f58c00", "#ffe8cd"  # the 3 % band
#: Point colours by session (matplotlib's "tab10" palette).
PALETTE = (
    "#1f77b4", "#ff7f0e", "#2ca02c", "#9467bd", "#8c564b",
    "#e377c2", "#7f7f7f", "#bcbd22", "#17becf",
)
MARKER_SIZE = 7  # points


def render(fig: Figure, fmt: str = "png") -> bytes:
    """The figure as ``png``, ``svg`` or ``pdf`` bytes, at its own size in pixels."""
    if fmt not in FORMATS:
        raise ValueError(f"unknown plot format {fmt!r} (choose {', '.join(FORMATS)})")
    buffer = io.BytesIO()
    with rc_context({"svg.hashsalt": "rigkit"}):  # SVG ids the same on every run
        fig.savefig(buffer, format=fmt, dpi=fig.dpi, metadata=_metadata(fmt))
    return buffer.getvalue()


def _metadata(fmt: str) -> dict[str, str | None]:
    """No creation date: the same rows give the same file."""
    if fmt == "svg":
        return {"Date": None}
    if fmt == "pdf":
        return {"CreationDate": None}
    return {}


def _figure(size: tuple[int, int]) -> tuple[Figure, Axes]:
    fig = Figure(figsize=(size[0] / DPI, size[1] / DPI), dpi=DPI, layout="constrained")
    FigureCanvasAgg(fig)
    return fig, fig.add_subplot()


def _usable(rows: Sequence[Comparison]) -> list[Comparison]:
    return [
        r for r in rows
        if r.ok and math.isfinite(r.laser_range_m) and math.isfinite(r.estimate_range_m)
    ]


def _colours(rows: Sequence[Comparison]) -> dict[str, str]:
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


def _titles(fig: Figure, ax: Axes, title: str, subtitle: str, xlabel: str, ylabel: str) -> None:
    fig.suptitle(title, fontsize=14, fontweight="bold", color=INK)
    ax.set_title(subtitle, fontsize=10, color=GREY)
    ax.set_xlabel(xlabel, color=INK)
    ax.set_ylabel(ylabel, color=INK)
    ax.grid(True, color="#e4e4e4", linewidth=0.8, zorder=0)


def _empty(title: str, xlabel: str, ylabel: str, size: tuple[int, int]) -> Figure:
    fig, ax = _figure(size)
    _titles(fig, ax, title, "no comparisons", xlabel, ylabel)
    ax.text(0.5, 0.5, "no comparisons", transform=ax.transAxes, ha="center", va="center",
            fontsize=16, color=GREY)
    return fig


def _widen(lo: float, hi: float) -> tuple[float, float]:
    """A non-empty span around ``[lo, hi]`` (never collapsed to a point)."""
    lo, hi = min(lo, hi), max(lo, hi)
    if hi - lo < 1e-9 * max(1.0, abs(lo), abs(hi)):
        pad = max(1.0, 0.05 * abs(lo))
        return lo - pad, hi + pad
    return lo, hi


def _scatter(
    ax: Axes,
    rows: Sequence[Comparison],
    colours: dict[str, str],
    xys: Callable[[Comparison], tuple[float, float, float]],
    diagonal: bool = False,
) -> None:
    """Markers with one-sigma error bars per session, outliers ringed and labelled.

    Labels go above the point for a positive error and below for a negative one; with
    ``diagonal`` (points along y = x) also left or right, away from the diagonal.
    """
    counts = Counter(r.session for r in rows)
    for session, colour in colours.items():
        mine = [xys(r) for r in rows if r.session == session]
        xs, ys, sigmas = ([p[i] for p in mine] for i in range(3))
        ax.errorbar(xs, ys, yerr=[s if math.isfinite(s) else 0.0 for s in sigmas], fmt="none",
                    ecolor=GREY, elinewidth=1, capsize=4, zorder=3)
        points = ax.scatter(xs, ys, s=MARKER_SIZE**2, color=colour, edgecolors=INK,
                            linewidths=0.8, zorder=4, label=f"{session} ({counts[session]})")
        points.set_gid(f"points:{session}")
    outliers = [r for r in rows if is_outlier(r)]
    if not outliers:
        return
    xy = [xys(r)[:2] for r in outliers]
    ring = ax.scatter([p[0] for p in xy], [p[1] for p in xy], s=(MARKER_SIZE + 8) ** 2,
                      facecolors="none", edgecolors=OUTLIER, linewidths=2, zorder=5,
                      label=f"beyond {LOOSE_PCT:g} %")
    ring.set_gid("outliers")
    for r, (x, y) in zip(outliers, xy, strict=True):
        _label(ax, x, y, f"{r.target} {r.error_pct:+.1f} %", r.error_pct > 0,
               left=diagonal and r.error_pct > 0)


def _label(ax: Axes, x: float, y: float, text: str, above: bool, left: bool = False) -> None:
    """A red label in a white box diagonally beside a point."""
    ax.annotate(
        text, (x, y), xytext=(-10 if left else 10, 10 if above else -10),
        textcoords="offset points", ha="right" if left else "left",
        va="bottom" if above else "top", color=OUTLIER, fontsize=9, zorder=6,
        bbox={"boxstyle": "square,pad=0.2", "facecolor": "white", "edgecolor": OUTLIER},
        annotation_clip=False,
    )


def _bands(
    ax: Axes, xs: list[float], edges: Callable[[float], tuple[list[float], list[float]]]
) -> None:
    """The 3 % and 1 % bands at ``xs``: ``edges(fraction)`` gives their lower and upper
    y values. Each is a fill under the grid with dashed edge lines above it (the grid
    would otherwise hide an edge that falls on a grid line)."""
    for pct, fill, edge in ((LOOSE_PCT, FILL_LOOSE, BAND_LOOSE),
                            (TIGHT_PCT, FILL_TIGHT, BAND_TIGHT)):
        lower, upper = edges(pct / 100)
        band = ax.fill_between(xs, lower, upper, facecolor=fill, edgecolor=edge, linewidth=0,
                               zorder=1, label=f"+/-{pct:g} %")
        band.set_gid(f"band-{pct:g}")
        for ys in (lower, upper):
            ax.plot(xs, ys, color=edge, linestyle="--", linewidth=1, zorder=1.8)


def _legend(ax: Axes) -> None:
    ax.legend(loc="best", fontsize=9, framealpha=0.9, ncols=2)


def plot_estimate_vs_laser(
    rows: Sequence[Comparison], size: tuple[int, int] = PLOT_SIZE
) -> Figure:
    """Estimated range against laser range; both axes show the same span, in metres."""
    title = "Estimated range vs laser range"
    xlabel, ylabel = "laser range (m)", "estimated range (m)"
    usable = _usable(rows)
    if not usable:
        return _empty(title, xlabel, ylabel, size)
    fig, ax = _figure(size)
    _titles(fig, ax, title, _subtitle(rows, len(usable)), xlabel, ylabel)
    a, b = _range_axis(usable)
    line = [a, b]
    _bands(ax, line, lambda k: ([a * (1 - k), b * (1 - k)], [a * (1 + k), b * (1 + k)]))
    (centre,) = ax.plot(line, line, color=INK, linewidth=2, zorder=2, label="estimate = laser")
    centre.set_gid("centre-line")
    _scatter(ax, usable, _colours(usable),
             lambda r: (r.laser_range_m, r.estimate_range_m, r.estimate_sigma_m), diagonal=True)
    ax.set_xlim(a, b)
    ax.set_ylim(a, b)
    for axis in (ax.xaxis, ax.yaxis):
        axis.set_major_locator(MaxNLocator(nbins=6, steps=[1, 2, 5, 10]))
    _legend(ax)
    return fig


def _range_axis(rows: Sequence[Comparison]) -> tuple[float, float]:
    """The common x and y span: all ranges plus 5 %, and at least 4 x the 3 % band's
    half-width so that a few close points still show the bands."""
    values = [r.laser_range_m for r in rows] + [r.estimate_range_m for r in rows]
    lo, hi = _widen(min(values), max(values))
    pad = 0.05 * (hi - lo)
    lo, hi = lo - pad, hi + pad
    min_span = 4 * LOOSE_PCT / 100 * max(abs(lo), abs(hi))
    if hi - lo < min_span:
        mid = (lo + hi) / 2
        lo, hi = mid - min_span / 2, mid + min_span / 2
    return lo, hi


def plot_error_vs_range(
    rows: Sequence[Comparison],
    size: tuple[int, int] = PLOT_SIZE,
    max_axis_pct: float = MAX_ERROR_AXIS_PCT,
) -> Figure:
    """Signed error (% of laser range) against laser range.

    The y axis is symmetric, at least +/-4 % and at most ``max_axis_pct``; errors beyond
    it are drawn as triangles at the top or bottom edge, labelled with their error.
    """
    title = "Range error vs laser range"
    xlabel = "laser range (m)"
    ylabel = "error, estimate - laser (% of laser range)"
    usable = _usable(rows)
    if not usable:
        return _empty(title, xlabel, ylabel, size)
    span = _error_span(usable, max_axis_pct)
    inside = [r for r in usable if -span <= r.error_pct <= span]
    outside = [r for r in usable if not -span <= r.error_pct <= span]
    subtitle = _subtitle(rows, len(usable))
    if outside:
        subtitle += f"; {len(outside)} beyond the axis drawn as triangles"
    fig, ax = _figure(size)
    _titles(fig, ax, title, subtitle, xlabel, ylabel)
    ranges = [r.laser_range_m for r in usable]
    lo, hi = _widen(min(ranges), max(ranges))
    pad = 0.05 * (hi - lo)
    xa, xb = lo - pad, hi + pad
    _bands(ax, [xa, xb], lambda k: ([-100 * k] * 2, [100 * k] * 2))
    (centre,) = ax.plot([xa, xb], [0.0, 0.0], color=INK, linewidth=2, zorder=2,
                        label="zero error")
    centre.set_gid("centre-line")
    colours = _colours(usable)
    _scatter(ax, inside, {s: c for s, c in colours.items()
                          if any(r.session == s for r in inside)}, _error_xys)
    _off_scale(ax, outside, colours, span)
    ax.set_xlim(xa, xb)
    ax.set_ylim(-span, span)
    ax.xaxis.set_major_locator(MaxNLocator(nbins=6, steps=[1, 2, 5, 10]))
    ax.yaxis.set_major_locator(MaxNLocator(nbins=8, steps=[1, 2, 5, 10], symmetric=True))
    ax.yaxis.set_major_formatter(lambda value, _: f"{value:+g}" if value else "0")
    _legend(ax)
    return fig


def _error_span(rows: Sequence[Comparison], max_axis_pct: float) -> float:
    """Half the y axis: the largest error plus 15 %, at least 4 % (the 3 % band shows),
    at most ``max_axis_pct``."""
    floor = LOOSE_PCT + 1
    worst = max(abs(r.error_pct) for r in rows)
    return min(max(floor, 1.15 * worst), max(max_axis_pct, floor))


def _error_xys(r: Comparison) -> tuple[float, float, float]:
    return r.laser_range_m, r.error_pct, 100 * r.estimate_sigma_m / r.laser_range_m


def _off_scale(
    ax: Axes, rows: Sequence[Comparison], colours: dict[str, str], span: float
) -> None:
    """A triangle at the top or bottom edge for each error beyond the y axis, labelled."""
    edge = 0.97 * span
    for sign, marker in ((1, "^"), (-1, "v")):
        mine = [r for r in rows if math.copysign(1, r.error_pct) == sign]
        if not mine:
            continue
        marks = ax.scatter([r.laser_range_m for r in mine], [sign * edge] * len(mine),
                           marker=marker, s=(MARKER_SIZE + 5) ** 2,
                           color=[colours[r.session] for r in mine], edgecolors=OUTLIER,
                           linewidths=2, zorder=5, clip_on=False)
        marks.set_gid("off-scale")
        for r in mine:
            _label(ax, r.laser_range_m, sign * edge, f"{r.target} {r.error_pct:+.1f} %",
                   above=sign < 0)
