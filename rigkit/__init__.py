"""rigkit: dense metric depth beyond LiDAR range from three telephoto cameras."""

from __future__ import annotations

import os

# OpenCV's decoders refuse an image of more pixels than this: the largest frame rigkit
# takes (rigkit.imagefile.imagesize.MAX_FRAME_PIXELS), so that no decoder allocates for a
# header rigkit's own check could not read. OpenCV reads it once, when it is first
# imported, which rigkit's modules do after this line; a value already set is kept.
os.environ.setdefault("OPENCV_IO_MAX_IMAGE_PIXELS", "250000000")

from rigkit.errors import InputError, PipelineError, RigkitError

__version__ = "0.1.0"

__all__ = ["InputError", "PipelineError", "RigkitError", "__version__"]
