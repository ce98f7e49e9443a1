"""A session's three frames as the pipeline's grey images (RAW or ordinary image files)."""

from __future__ import annotations

import numpy as np

from rigkit.capture.rawio import is_raw, load_linear_grey, to_pipeline
from rigkit.capture.session import DERIVED_DIR, POSITIONS, Session
from rigkit.errors import InputError


def load_frames(session: Session) -> list[np.ndarray]:
    """Left, right and back as (H, W) float32 grey in [0, 255], ready for the pipeline.

    RAW frames are decoded linearly (cached in ``derived/`` by content hash) and share
    one brightness scale; the three frames must be all RAW or all ordinary images.
    """
    paths = [session.frame_path(position) for position in POSITIONS]
    kinds = {is_raw(path) for path in paths}
    if len(kinds) > 1:
        listed = ", ".join(f"{pos} {session.frames[pos].file}" for pos in POSITIONS)
        raise InputError(
            f"{session.path}: mixes RAW and non-RAW frames ({listed}); their brightness "
            "cannot be matched"
        )
    cache = session.path / DERIVED_DIR
    cache.mkdir(exist_ok=True)
    greys = [
        load_linear_grey(path, cache, session.frames[pos].sha256)
        for pos, path in zip(POSITIONS, paths, strict=True)
    ]
    return to_pipeline(greys, linear=kinds == {True})
