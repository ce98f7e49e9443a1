"""The field TUI's screens, one module per step: start (sessions), rig, left/right/back
positions, laser targets, processing. Each shows what the library computes, changes
the session only through :mod:`rigkit.capture`, and asks the app for everything else
with a message (:mod:`rigkit.tui.messages`)."""

from rigkit.tui.screens.position import PositionScreen
from rigkit.tui.screens.process import ProcessScreen
from rigkit.tui.screens.rig import RigScreen
from rigkit.tui.screens.start import StartScreen
from rigkit.tui.screens.targets import TargetsScreen

__all__ = ["PositionScreen", "ProcessScreen", "RigScreen", "StartScreen", "TargetsScreen"]
