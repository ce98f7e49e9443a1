"""rigkit: dense metric depth beyond LiDAR range from three telephoto cameras."""

from __future__ import annotations

from rigkit.errors import InputError, PipelineError, RigkitError

__version__ = "0.1.0"

__all__ = ["InputError", "PipelineError", "RigkitError", "__version__"]
