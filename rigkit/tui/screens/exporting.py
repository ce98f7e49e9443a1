"""The verdict screen's export: ``e`` writes the session's latest results into
``SESSION/export/`` (PLY and LAS: on the map when the session knows where the tripod
stood and its targets give the camera's orientation, else in the camera frame, saying
why) in a worker thread, and says where on the screen's ``#stage`` line."""

from __future__ import annotations

from textual import work
from textual.binding import Binding
from textual.widgets import Static

from rigkit.capture import RESULTS_DIR
from rigkit.errors import RigkitError
from rigkit.export import DEFAULT_FORMATS, EXPORT_DIR, Exported, export_path
from rigkit.tui.screens.common import StepScreen, escape, session_of


class ExportingScreen(StepScreen):
    """A step screen with a ``#stage`` line that can export the session's results."""

    BINDINGS = [Binding("e", "export", "export")]

    def running(self) -> bool:
        """Whether processing is under way (what it writes is not there yet)."""
        return False

    def action_export(self) -> None:
        if self.running():
            self.notify("processing is under way: e exports its results when it is done",
                        severity="warning")
            return
        if not (session_of(self).path / RESULTS_DIR / "depth.npy").is_file():
            self.notify("nothing to export yet: press r to process first", severity="warning")
            return
        self.query_one("#stage", Static).update("exporting ...")
        self._export()

    @work(thread=True, exclusive=True, group="export")
    def _export(self) -> None:
        path = session_of(self).path
        try:
            done = export_path(path, path / EXPORT_DIR, DEFAULT_FORMATS)
        except RigkitError as exc:
            self.deliver(self._said, f"[b $error]✘ {escape(str(exc))}[/]")
            return
        self.deliver(self._said, _exported(done))

    def _said(self, markup: str) -> None:
        self.query_one("#stage", Static).update(markup)


def _exported(done: Exported) -> str:
    where = "on the map" if done.georef is not None else "in the camera frame"
    folder = done.files[0].parent
    names = ", ".join(f.name for f in done.files)
    why = "" if done.note is None else f" [$warning](not on the map: {escape(done.note)})[/]"
    return (f"[b $success]✔[/] {done.points} points {where}: "
            f"{escape(names)} in {escape(str(folder))}{why}")
