"""Synthetic three-view scenes with exact ground truth (``rigkit synth``)."""

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
