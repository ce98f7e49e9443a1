"""Texture with an exact sub-pixel translation, for the matching stages' tests."""

from __future__ import annotations

import numpy as np


def plane_waves(shift: tuple[float, float], size: tuple[int, int] = (384, 384)) -> np.ndarray:
    """(H, W) float64 unit-variance texture, a sum of 150 plane waves of random direction
    and period 3-50 px (always the same ones), sampled at pixel centres moved by
    ``shift`` (x, y) px: the texture at x in an unshifted image is at x - shift here."""
    rng = np.random.default_rng(3)
    h, w = size
    yy, xx = np.mgrid[0:h, 0:w].astype(np.float64)
    xx, yy = xx + shift[0], yy + shift[1]
    image = np.zeros((h, w))
    for _ in range(150):
        f, turn, phase = rng.uniform(0.02, 0.3), *rng.uniform(0, 2 * np.pi, 2)
        image += np.cos(2 * np.pi * f * (np.cos(turn) * xx + np.sin(turn) * yy) + phase)
    return image / image.std()
