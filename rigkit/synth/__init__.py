"""Synthetic three-view scenes with exact ground truth (``rigkit synth``).

Its public names are imported on first use (:mod:`rigkit.core.lazy`).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from rigkit.core.lazy import exports

if TYPE_CHECKING:
    from rigkit.synth.io import SceneTruth, load_scene, write_scene
    from rigkit.synth.scene import Scene, SynthParams, field_params, generate_scene

__all__ = [
    "Scene",
    "SceneTruth",
    "SynthParams",
    "field_params",
    "generate_scene",
    "load_scene",
    "write_scene",
]

__getattr__ = exports(__name__, {
    "Scene": "scene",
    "SceneTruth": "io",
    "SynthParams": "scene",
    "field_params": "scene",
    "generate_scene": "scene",
    "load_scene": "io",
    "write_scene": "io",
})
