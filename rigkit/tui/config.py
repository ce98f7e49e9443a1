"""What ``rigkit field`` was started with (no Textual here: the command builds it)."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from rigkit.synth.demo import Demo
from rigkit.tui.watch import SETTLE_S


@dataclass(frozen=True)
class FieldConfig:
    """``capture``: the folder whose sessions the start screen lists. ``session``: a
    session to resume, or to create with ``rig``. ``watch``: folder frames arrive in.
    ``port``: the rangefinder's pyserial URL (None: readings typed in). ``demo``: the
    demo's folders, when running it. ``graphics``: let textual-image use the terminal's
    graphics protocol for previews when it has one (else half blocks). ``settle_s``: how
    long a new file's size must stay the same before it counts, seconds."""

    capture: Path
    session: Path | None = None
    rig: Path | None = None
    watch: Path | None = None
    port: str | None = None
    protocol: str = "trupulse"
    demo: Demo | None = None
    graphics: bool = True
    settle_s: float = SETTLE_S
