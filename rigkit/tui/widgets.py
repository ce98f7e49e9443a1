"""Widgets of the field TUI: an image drawn with half blocks, with a cursor and marks.

Each terminal cell shows two image pixels, one above the other: the upper half block
``▀`` in the top pixel's colour on the bottom pixel's colour. That works in every
terminal with 24-bit or 256 colours, over SSH too, and is exact enough to aim at a
target with the zoom. (textual-image does the same as its fallback; the cursor and the
marks need the pixel grid, so this widget draws its own.)
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from rich.color import Color
from rich.segment import Segment
from rich.style import Style
from textual.geometry import Size
from textual.strip import Strip
from textual.widget import Widget

CURSOR_RGB = (255, 0, 255)
MARK_RGB = (255, 255, 0)
ZOOMS = (1, 2, 4, 8, 16)


@dataclass(frozen=True)
class Mark:
    """A labelled point in image pixels (u right, v down, centres at integers)."""

    u: float
    v: float
    label: str


def stretch(grey: np.ndarray) -> np.ndarray:
    """(H, W) grey -> uint8 with its 1st and 99th percentiles at 0 and 255: readable in
    sunlight whatever the exposure (for display only; checks use the frame itself)."""
    low, high = np.percentile(grey, [1, 99])
    scaled = (grey.astype(np.float32) - low) * (255.0 / max(float(high - low), 1e-6))
    return np.clip(scaled, 0, 255).astype(np.uint8)


class PixelView(Widget):
    """An RGB image ((H, W, 3) uint8) scaled into the widget, aspect kept.

    With a cursor (image px) the view can zoom in around it; :meth:`move_cursor` steps
    it by whole pixels of the shown image. Marks are drawn as small yellow squares.
    """

    DEFAULT_CSS = "PixelView { width: 1fr; height: 1fr; }"

    def __init__(self, image: np.ndarray | None = None, *, cursor: bool = False,
                 id: str | None = None) -> None:
        super().__init__(id=id)
        self._image = image
        self._cursor: tuple[int, int] | None = None
        self._want_cursor = cursor
        self._zoom_index = 0
        self._marks: tuple[Mark, ...] = ()
        self._cells: np.ndarray | None = None
        self._strips: dict[int, Strip] = {}
        if image is not None:
            self.set_image(image)

    # -- state ----------------------------------------------------------------------------

    def set_image(self, image: np.ndarray | None) -> None:
        """Show ``image`` ((H, W, 3) uint8, or (H, W) grey, stretched to full contrast for
        the eye) or nothing."""
        if image is not None and image.ndim == 2:
            image = np.repeat(stretch(image)[..., None], 3, axis=2)
        self._image = image
        if image is not None and self._want_cursor and self._cursor is None:
            self._cursor = (image.shape[1] // 2, image.shape[0] // 2)
        self._refresh_cells()

    def set_marks(self, marks: Sequence[Mark]) -> None:
        self._marks = tuple(marks)
        self._refresh_cells()

    @property
    def cursor(self) -> tuple[int, int] | None:
        """The cursor in image pixels (u, v), or None."""
        return self._cursor

    @property
    def zoom(self) -> int:
        return ZOOMS[self._zoom_index]

    def move_cursor(self, du: int, dv: int) -> None:
        """Move the cursor by (du, dv) shown pixels: finer when zoomed in."""
        if self._image is None or self._cursor is None:
            return
        step = max(1.0, self._source_px_per_sample())
        height, width = self._image.shape[:2]
        u = min(max(round(self._cursor[0] + du * step), 0), width - 1)
        v = min(max(round(self._cursor[1] + dv * step), 0), height - 1)
        self._cursor = (u, v)
        self._refresh_cells()

    def change_zoom(self, steps: int) -> None:
        self._zoom_index = min(max(self._zoom_index + steps, 0), len(ZOOMS) - 1)
        self._refresh_cells()

    # -- drawing --------------------------------------------------------------------------

    def on_resize(self) -> None:
        self._refresh_cells()

    def _source_px_per_sample(self) -> float:
        if self._image is None:
            return 1.0
        height, width = self._image.shape[:2]
        cols, rows = max(self.size.width, 1), max(self.size.height * 2, 1)
        return max(width / cols, height / rows) / self.zoom

    def _region(self) -> tuple[float, float, float]:
        """(u0, v0, px per sample) of the shown part of the image."""
        assert self._image is not None
        height, width = self._image.shape[:2]
        per = self._source_px_per_sample()
        cols, rows = max(self.size.width, 1), max(self.size.height * 2, 1)
        if self._cursor is None or self.zoom == 1:
            return (width - cols * per) / 2, (height - rows * per) / 2, per
        u0 = min(max(self._cursor[0] - cols * per / 2, 0.0), max(width - cols * per, 0.0))
        v0 = min(max(self._cursor[1] - rows * per / 2, 0.0), max(height - rows * per, 0.0))
        return u0, v0, per

    def _refresh_cells(self) -> None:
        self._cells = None if self._image is None else self._sample()
        self._strips = {}  # rows drawn since, kept until the next change
        self.refresh()

    def _sample(self) -> np.ndarray:
        """(2 rows, cols, 3) uint8 samples of the shown region, with cursor and marks."""
        assert self._image is not None
        height, width = self._image.shape[:2]
        cols, rows = max(self.size.width, 1), max(self.size.height * 2, 1)
        u0, v0, per = self._region()
        us = u0 + (np.arange(cols) + 0.5) * per - 0.5
        vs = v0 + (np.arange(rows) + 0.5) * per - 0.5
        inside_u = (us > -1) & (us < width)
        inside_v = (vs > -1) & (vs < height)
        ui = np.clip(np.rint(us), 0, width - 1).astype(int)
        vi = np.clip(np.rint(vs), 0, height - 1).astype(int)
        cells = self._image[vi][:, ui].copy()
        cells[~inside_v] = 0
        cells[:, ~inside_u] = 0
        def at(u: float, v: float) -> tuple[int, int]:  # the sample showing pixel (u, v)
            return round((u + 0.5 - u0) / per - 0.5), round((v + 0.5 - v0) / per - 0.5)

        for mark in self._marks:
            self._paint(cells, at(mark.u, mark.v), MARK_RGB, 1)
        if self._cursor is not None:
            self._paint(cells, at(*self._cursor), CURSOR_RGB, 2, cross=True)
        return cells

    @staticmethod
    def _paint(cells: np.ndarray, at: tuple[int, int], rgb: tuple[int, int, int], half: int,
               cross: bool = False) -> None:
        """A filled square of side 2 half + 1 samples, or a cross with a hole in the
        middle (the pixel under the cursor stays visible)."""
        rows, cols = cells.shape[:2]
        cx, cy = at
        for dy in range(-half, half + 1):
            for dx in range(-half, half + 1):
                if cross and (dx * dy != 0 or dx == dy == 0):
                    continue
                if 0 <= cy + dy < rows and 0 <= cx + dx < cols:
                    cells[cy + dy, cx + dx] = rgb

    def get_content_height(self, container: Size, viewport: Size, width: int) -> int:
        return container.height

    def render_line(self, y: int) -> Strip:
        cells = self._cells
        width = self.size.width
        if cells is None or 2 * y + 1 >= cells.shape[0]:
            return Strip.blank(width)
        if y not in self._strips:  # drawn once per change, not at every refresh
            top, bottom = cells[2 * y], cells[2 * y + 1]
            segments = [
                Segment("▀", Style(color=Color.from_rgb(*t), bgcolor=Color.from_rgb(*b)))
                for t, b in zip(top.tolist(), bottom.tolist(), strict=True)
            ]
            self._strips[y] = Strip(segments, width)
        return self._strips[y]
