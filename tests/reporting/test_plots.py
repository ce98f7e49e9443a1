"""The report plots (matplotlib): what is drawn where, read from the figure's artists
(their ids name what they show) and from the rendered image."""

from __future__ import annotations

import io
import math

import numpy as np
import pytest
from matplotlib.collections import PathCollection
from matplotlib.colors import to_rgba
from matplotlib.figure import Figure
from PIL import Image

from rigkit.capture.comparisons import STATUS_NO_ESTIMATE, Comparison
from rigkit.reporting.plots import (
    OUTLIER,
    PALETTE,
    plot_error_vs_range,
    plot_estimate_vs_laser,
    render,
)
from tests.conftest import make_row as _row


def _artists(fig: Figure, gid: str) -> list:
    return [a for a in fig.axes[0].get_children() if a.get_gid() == gid]


def _points(fig: Figure, session: str = "field-1") -> list[tuple[float, float]]:
    """The session's markers in display pixels (x right, y up), left to right."""
    (points,) = _artists(fig, f"points:{session}")
    fig.canvas.draw()
    return sorted(map(tuple, points.get_offset_transform().transform(points.get_offsets())))


def _pixels(fig: Figure) -> np.ndarray:
    """The figure rendered as PNG, read back: (H, W, 3) uint8."""
    return np.asarray(Image.open(io.BytesIO(render(fig, "png"))).convert("RGB"))


PLOT_ROWS = [
    _row("near", 200.0, -2.0),
    _row("far", 400.0, 2.0),
    _row("gone", 300.0, 0.0, status=STATUS_NO_ESTIMATE),
]


def test_estimate_vs_laser_puts_points_on_the_diagonal() -> None:
    fig = plot_estimate_vs_laser(PLOT_ROWS)
    assert _pixels(fig).shape == (700, 1000, 3)
    (x1, y1), (x2, y2) = _points(fig)  # the no_estimate row is not drawn
    assert x2 - x1 > 200 and y2 - y1 > 150  # the far point is right of and above the near one
    (points,) = _artists(fig, "points:field-1")
    assert np.allclose(points.get_offsets(), [[200.0, 196.0], [400.0, 408.0]])
    (centre,) = _artists(fig, "centre-line")
    assert list(centre.get_xdata()) == list(centre.get_ydata())  # estimate = laser
    assert _artists(fig, "band-1") and _artists(fig, "band-3")
    ax = fig.axes[0]
    assert ax.get_xlim() == ax.get_ylim()  # both axes show the same span
    assert not _artists(fig, "outliers")  # no outlier, no red ring


def test_error_vs_range_puts_points_either_side_of_zero() -> None:
    fig = plot_error_vs_range(PLOT_ROWS)
    assert _pixels(fig).shape == (700, 1000, 3)
    (x1, y1), (x2, y2) = _points(fig)
    assert x2 - x1 > 200 and y2 - y1 > 100  # -2 % below, +2 % above
    (centre,) = _artists(fig, "centre-line")
    assert set(centre.get_ydata()) == {0.0}
    xs = centre.get_xdata()
    assert min(xs) < 200.0 and max(xs) > 400.0  # the zero line spans the points
    zero = fig.axes[0].transData.transform((300.0, 0.0))[1]
    assert zero == pytest.approx((y1 + y2) / 2, abs=1.0)  # half-way between +2 % and -2 %
    ylo, yhi = fig.axes[0].get_ylim()
    assert ylo == -yhi and yhi >= 4.0  # symmetric, the 3 % band shows


def test_outliers_are_ringed_and_plot_size_is_a_parameter() -> None:
    rows = [*PLOT_ROWS, _row("mast", 350.0, 5.0)]
    for plot, y in ((plot_estimate_vs_laser, 350.0 * 1.05), (plot_error_vs_range, 5.0)):
        fig = plot(rows, size=(800, 600))
        assert _pixels(fig).shape == (600, 800, 3)
        (ring,) = _artists(fig, "outliers")
        assert np.allclose(ring.get_offsets(), [[350.0, y]])
        assert tuple(ring.get_edgecolor()[0]) == to_rgba(OUTLIER)
        labels = [t.get_text() for t in fig.axes[0].texts]
        assert "mast +5.0 %" in labels


def test_errors_beyond_the_axis_are_drawn_at_the_edge() -> None:
    rows = [_row("a", 250.0, 0.4), _row("b", 400.0, 80.0), _row("c", 300.0, -30.0)]
    fig = plot_error_vs_range(rows)
    ylo, yhi = fig.axes[0].get_ylim()
    assert yhi == 10.0 and ylo == -10.0  # at most the 10 % axis
    marks = _artists(fig, "off-scale")
    edges = sorted(tuple(p) for m in marks for p in m.get_offsets().tolist())
    assert np.allclose(edges, [(300.0, -9.7), (400.0, 9.7)])
    assert "2 without" not in fig.axes[0].get_title()
    assert "2 beyond the axis drawn as triangles" in fig.axes[0].get_title()


@pytest.mark.parametrize(
    "rows",
    [
        [],
        [_row("a", 300.0, 0.0, status=STATUS_NO_ESTIMATE)],
        [_row("a", 302.0, 0.4)],
        [_row("a", 300.0, 0.4), _row("b", 300.0, -0.6), _row("c", 300.0, -2.0)],
        [_row("a", 250.0, 0.4), _row("b", 400.0, 80.0), _row("c", math.nan, 0, status="x")],
    ],
    ids=["none", "no-usable", "single", "same-range", "off-scale"],
)
def test_plots_handle_edge_cases(rows: list[Comparison]) -> None:
    for plot in (plot_estimate_vs_laser, plot_error_vs_range):
        img = _pixels(plot(rows))
        assert img.shape == (700, 1000, 3)
        assert (img < 128).any(axis=2).sum() > 500  # text and axes drawn
    usable = [r for r in rows if r.ok]
    fig = plot_error_vs_range(rows)
    drawn = _artists(fig, "points:field-1") + _artists(fig, "off-scale")
    assert sum(len(a.get_offsets()) for a in drawn) == len(usable)
    for a in drawn:
        assert isinstance(a, PathCollection)
    if usable:
        (points,) = _artists(plot_estimate_vs_laser(rows), "points:field-1")
        assert tuple(points.get_facecolor()[0]) == to_rgba(PALETTE[0])


def test_svg_and_pdf() -> None:
    fig = plot_estimate_vs_laser(PLOT_ROWS)
    assert b"<svg" in render(fig, "svg")[:500]
    assert render(fig, "pdf").startswith(b"%PDF")
    assert render(fig, "svg") == render(fig, "svg")  # no timestamp: same rows, same file
    with pytest.raises(ValueError, match="unknown plot format"):
        render(fig, "gif")
