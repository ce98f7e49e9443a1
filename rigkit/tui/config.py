"""What ``rigkit field`` was started with (no Textual here: the command builds it)."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:  # the demo's libraries load after the first screen
    from rigkit.synth.demo import Demo

SETTLE_S = 0.6
"""How long a new file's size must stay the same before it counts, seconds (the watcher's
default, :mod:`rigkit.tui.watch`)."""


@dataclass(frozen=True)
class FieldConfig:
    """``capture``: the folder whose sessions the start screen lists. ``session``: a
    session to resume, or to create with ``rig``. ``watch``: folder frames arrive in.
    ``port``: the rangefinder's pyserial URL (None: readings typed in). ``demo``: the
    demo's folders, when running it (rendered and its session created when the app
    starts, :meth:`rigkit.synth.demo.Demo.prepare`). ``graphics``: let textual-image use
    the terminal's graphics protocol for previews when it has one (else half blocks).
    ``settle_s``: how long a new file's size must stay the same before it counts,
    seconds."""

    capture: Path
    session: Path | None = None
    rig: Path | None = None
    watch: Path | None = None
    port: str | None = None
    protocol: str = "trupulse"
    demo: Demo | None = None
    graphics: bool = True
    settle_s: float = SETTLE_S
