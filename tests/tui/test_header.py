"""The field TUI's header (rigkit.tui.header): its title follows the app's, and a title
changed after its title widget went (a screen replaced under it) ends nothing."""

from __future__ import annotations

import pytest
from textual.app import App, ComposeResult
from textual.css.query import NoMatches
from textual.widgets import Header
from textual.widgets._header import HeaderTitle

from rigkit.tui.header import FieldHeader
from tests.tui.conftest import synchronous


class _Titled(App):
    def __init__(self, header: type[Header]) -> None:
        super().__init__()
        self.header = header

    def compose(self) -> ComposeResult:
        yield self.header()


def _shown(app: App) -> str:
    return str(app.query_one(HeaderTitle).render())


@synchronous
async def test_the_title_follows_the_app() -> None:
    app = _Titled(FieldHeader)
    async with app.run_test(size=(60, 5)) as pilot:
        app.title, app.sub_title = "rigkit field", "session-1"
        await pilot.pause()
        assert "rigkit field" in _shown(app) and "session-1" in _shown(app)
        app.sub_title = "session-2"
        await pilot.pause()
        assert "session-2" in _shown(app)


async def _title_changed_after_its_widget_went(app: App) -> None:
    async with app.run_test(size=(60, 5)) as pilot:
        await pilot.pause()
        await app.query_one(HeaderTitle).remove()
        app.sub_title = "changed"
        await pilot.pause()
        assert app.is_running


@synchronous
async def test_a_title_changed_after_its_widget_went_ends_nothing() -> None:
    app = _Titled(FieldHeader)
    await _title_changed_after_its_widget_went(app)
    assert app._exception is None


@synchronous
async def test_textuals_own_header_still_ends_the_app_there() -> None:
    """The witness of what FieldHeader is for: where a Textual upgrade makes this fail,
    its header is safe, and FieldHeader can go."""
    with pytest.raises((NoMatches, AssertionError)):
        await _title_changed_after_its_widget_went(_Titled(Header))
