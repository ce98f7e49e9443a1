"""The half-block image view (cursor, zoom, marks) and the preview's choice of renderer."""

from __future__ import annotations

import numpy as np
import pytest
from textual.app import App, ComposeResult
from textual.widget import Widget

from rigkit.tui import previews
from rigkit.tui.widgets import CURSOR_RGB, MARK_RGB, Mark, PixelView, stretch
from tests.tui.conftest import synchronous


class Holder(App[None]):
    def __init__(self, widget: Widget) -> None:
        super().__init__()
        self.widget = widget

    def compose(self) -> ComposeResult:
        yield self.widget


def _colours(view: PixelView) -> set[tuple[int, int, int]]:
    cells = view._cells
    assert cells is not None
    return {tuple(int(c) for c in rgb) for rgb in cells.reshape(-1, 3)}


@synchronous
async def test_cursor_moves_by_shown_pixels_and_stays_inside() -> None:
    image = np.zeros((100, 200), np.uint8)
    view = PixelView(cursor=True)
    async with Holder(view).run_test(size=(40, 20)) as pilot:
        view.set_image(image)
        await pilot.pause()
        assert view.cursor == (100, 50)
        view.move_cursor(1, 0)  # 200 px over 40 cells: 5 px per shown pixel
        assert view.cursor == (105, 50)
        view.change_zoom(+2)  # 4x: finer steps
        view.move_cursor(1, 0)
        assert view.cursor == (106, 50)
        view.move_cursor(-500, 500)
        assert view.cursor == (0, 99)
        assert CURSOR_RGB in _colours(view)


@synchronous
async def test_zoomed_view_shows_the_pixel_under_the_cursor_and_the_marks() -> None:
    image = np.zeros((64, 64), np.uint8)
    image[20, 30] = 255
    view = PixelView(cursor=True)
    async with Holder(view).run_test(size=(32, 16)) as pilot:
        view.set_image(image)
        view.set_marks([Mark(10, 10, "T1")])
        await pilot.pause()
        assert MARK_RGB in _colours(view)
        view.move_cursor(-1, -6)  # from the centre, 2 px per shown pixel: to (30, 20)
        assert view.cursor == (30, 20)
        view.change_zoom(+4)  # 16x: one image pixel is 8 cells wide
        cells = view._cells
        assert cells is not None
        white = np.all(cells == 255, axis=2)
        rows, cols = np.nonzero(white)
        assert white.sum() >= 30  # the pixel, big, minus the cursor's arms
        assert abs(cols.mean() - 16) <= 4 and abs(rows.mean() - 16) <= 4  # in the middle


def test_stretch_spans_the_grey_levels() -> None:
    grey = np.linspace(40, 80, 1000, dtype=np.float32).reshape(10, 100)
    out = stretch(grey)
    assert out.dtype == np.uint8 and out.min() == 0 and out.max() == 255


@pytest.mark.filterwarnings("ignore:Image.Image.getdata is deprecated")
@synchronous
async def test_a_graphics_terminal_gets_textual_image(monkeypatch: pytest.MonkeyPatch) -> None:
    from textual_image.widget import Image

    image = np.zeros((48, 64), np.uint8)
    monkeypatch.setattr(previews, "HAS_GRAPHICS", True)
    widget = previews.preview_widget(image, graphics=True)
    assert isinstance(widget, Image)
    assert isinstance(previews.preview_widget(image, graphics=False), PixelView)
    async with Holder(widget).run_test(size=(40, 20)) as pilot:
        await pilot.pause()
        assert widget.size.width > 0
