"""The field TUI's header: Textual's, made safe against a screen replaced under it."""

from __future__ import annotations

from textual import events
from textual.widget import Widget
from textual.widgets import Header
from textual.widgets._header import HeaderTitle


class FieldHeader(Header):
    """Textual's header, whose title follows the app's and the screen's as before, but
    is updated only where its title widget still is. Textual's own update looks the
    title widget up when the change's turn comes; a screen replaced between a title's
    change and that turn (a session opening as the first screen goes) had lost it, and
    the lookup's error ended the app (the whole suite saw it once)."""

    def _on_mount(self, event: events.Mount) -> None:
        event.prevent_default()  # in place of Header's handler, not after it
        Widget._on_mount(self, event)  # what the handlers below Header's do
        for node, name in ((self.app, "title"), (self.app, "sub_title"),
                           (self.screen, "title"), (self.screen, "sub_title")):
            self.watch(node, name, self._set_title)

    def _set_title(self) -> None:
        for title in self.query(HeaderTitle):
            title.update(self.format_title())
