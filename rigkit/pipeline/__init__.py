"""The depth pipeline: pseudo-rectification, stereo, ambiguity removal, depth.

Its public names are imported on first use (:mod:`rigkit.core.lazy`): reading a frame
(:mod:`rigkit.imagefile.decode`) does not load every stage and SciPy with them.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from rigkit.core.lazy import exports

if TYPE_CHECKING:
    from rigkit.pipeline.estimate import DepthResult, estimate_depth
    from rigkit.pipeline.rig import RigGeometry

__all__ = ["DepthResult", "RigGeometry", "estimate_depth"]

__getattr__ = exports(__name__, {"DepthResult": "estimate", "estimate_depth": "estimate",
                                 "RigGeometry": "rig"})
