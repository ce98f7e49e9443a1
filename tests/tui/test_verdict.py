"""The process screen shows the verdict its run returned (rigkit.batch.process_session's
Outcome.verdict), not one it works out again; reopened, the one the run's record gives
(rigkit.reporting.verdict.run_verdict)."""

from __future__ import annotations

import pytest

from rigkit.capture.positioning import set_field_step
from rigkit.synth.demo import Demo
from rigkit.tui.screens import ProcessScreen
from tests.tui.conftest import opened, synchronous, text, wait_for
from tests.tui.test_flow import SIZE
from tests.tui.test_resume import app_on, framed


@pytest.mark.slow
@synchronous
async def test_the_verdict_shown_is_the_one_the_run_returned(
        demo: Demo, monkeypatch: pytest.MonkeyPatch) -> None:
    session = framed(demo, "verdict")
    set_field_step(session.path, "process")

    def again(*args: object, **kwargs: object) -> None:
        raise AssertionError("the screen worked the verdict out again")

    monkeypatch.setattr("rigkit.tui.screens.process.run_verdict", again)
    app = app_on(demo, session.path)
    async with app.run_test(size=SIZE) as pilot:
        await opened(pilot, app)
        await wait_for(pilot, lambda: isinstance(app.screen, ProcessScreen)
                       and "r: process" in text(app, "#stage"), "the process step")
        await pilot.press("r")
        await wait_for(pilot, lambda: "targets within" in text(app, "#verdict"), "the verdict",
                       60)
    assert app._exception is None
    monkeypatch.undo()  # reopened, the record's verdict: the same words
    app = app_on(demo, session.path)
    async with app.run_test(size=SIZE) as pilot:
        await opened(pilot, app)
        await wait_for(pilot, lambda: "latest run shown" in text(app, "#stage"), "the run")
        assert "targets within" in text(app, "#verdict")
