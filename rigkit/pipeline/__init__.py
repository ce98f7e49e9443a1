"""The depth pipeline: pseudo-rectification, stereo, ambiguity removal, depth."""

from rigkit.pipeline.estimate import DepthResult, RigGeometry, estimate_depth

__all__ = ["DepthResult", "RigGeometry", "estimate_depth"]
