"""The depth pipeline: pseudo-rectification, stereo, ambiguity removal, depth."""

from rigkit.pipeline.estimate import DepthResult, estimate_depth
from rigkit.pipeline.rig import RigGeometry

__all__ = ["DepthResult", "RigGeometry", "estimate_depth"]
