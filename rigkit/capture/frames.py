"""A session's three positions as the pipeline's grey images (RAW or ordinary image
files; a position's burst median-stacked into one), and the heat shimmer its bursts
show."""

from __future__ import annotations

import numpy as np

from rigkit.capture.rawio import is_raw, load_linear_grey, to_pipeline
from rigkit.capture.session import DERIVED_DIR, POSITIONS, Session
from rigkit.errors import InputError
from rigkit.pipeline.burst import stack_burst
from rigkit.pipeline.shimmer import Shimmer, burst_shimmer


def load_frames(session: Session) -> tuple[list[np.ndarray], tuple[Shimmer, str] | None]:
    """Left, right and back as (H, W) float32 grey in [0, 255], ready for the pipeline,
    and the heat shimmer between the first two frames of the first position with a
    burst (:func:`rigkit.pipeline.shimmer.burst_shimmer`; None for single frames).

    RAW frames are decoded linearly (cached in ``derived/`` by content hash) and share
    one brightness scale; the frames must be all RAW or all ordinary images. A burst is
    aligned and median-stacked (in linear light for RAW) into its position's image.
    """
    for position in POSITIONS:
        session.frame_path(position)  # InputError naming a missing position
    every = [session.path / f.file for pos in POSITIONS for f in session.bursts[pos]]
    kinds = {is_raw(path) for path in every}
    if len(kinds) > 1:
        listed = ", ".join(f"{pos} {session.frames[pos].file}" for pos in POSITIONS)
        raise InputError(
            f"{session.path}: mixes RAW and non-RAW frames ({listed}); their brightness "
            "cannot be matched"
        )
    linear = kinds == {True}
    cache = session.path / DERIVED_DIR
    cache.mkdir(exist_ok=True)
    greys, shimmer = [], None
    for position in POSITIONS:
        frames = [load_linear_grey(session.path / f.file, cache, f.sha256)
                  for f in session.bursts[position]]
        if shimmer is None and len(frames) > 1:
            shimmer = burst_shimmer(to_pipeline(frames[:2], linear=linear), position)
        greys.append(stack_burst(frames, f"{session.path}: {position} burst"))
    return to_pipeline(greys, linear=linear), shimmer
