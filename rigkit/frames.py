"""A session's three frames as the pipeline's grey images (RAW or ordinary image files)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from rigkit.errors import InputError
from rigkit.rawio import is_raw, load_linear_grey, to_pipeline
from rigkit.session import DERIVED_DIR, POSITIONS, Session


def image_size(path: Path, cache_dir: Path, sha256: str) -> tuple[int, int]:
    """(width, height) in px of the image rigkit decodes from ``path``.

    Decodes the file, which proves it readable (InputError naming it if not), and leaves
    a RAW file's decoded image in ``cache_dir`` under its content hash ``sha256``.
    """
    cache_dir.mkdir(parents=True, exist_ok=True)
    grey = load_linear_grey(path, cache_dir, sha256)
    return int(grey.shape[1]), int(grey.shape[0])


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
