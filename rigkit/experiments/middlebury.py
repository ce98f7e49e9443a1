"""The stereo stage on real imagery with ground truth: Middlebury's Motorcycle pair
(Scharstein et al., GCPR 2014), as scikit-image ships it (``skimage.data``: a rectified
741x500 pair with its ground-truth disparity; unknown ground truth is inf).

bad-N: the share of pixels whose disparity is off by more than N px, counted over all
pixels with ground truth (a pixel without an estimate counts as bad) and over the
pixels that have an estimate.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from rigkit.pipeline.stereo import SGBM, StereoMatcher

MARGIN_PX = 8  # px added to the ground truth's disparity range for the search


@dataclass(frozen=True)
class StereoScores:
    """Fractions in [0, 1] over ``judged`` pixels (finite ground truth)."""

    judged: int
    density: float
    bad1_all: float
    bad2_all: float
    bad1_est: float
    bad2_est: float


def motorcycle() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(left, right, ground truth): (H, W) float32 grey 0-255 and disparity px (inf = unknown)."""
    from skimage import color, data

    left, right, disp = data.stereo_motorcycle()
    grey = [(color.rgb2gray(im) * 255).astype(np.float32) for im in (left, right)]
    return grey[0], grey[1], disp.astype(np.float32)


def stereo_scores(estimate: np.ndarray, truth: np.ndarray) -> StereoScores:
    """Score a disparity map (H, W) px, NaN = none, against ``truth`` (inf = unknown)."""
    judged = np.isfinite(truth)
    est, gt = estimate[judged], truth[judged]
    has = np.isfinite(est)
    err = np.abs(est[has] - gt[has])
    n, m = int(judged.sum()), max(int(has.sum()), 1)
    bad = [int(np.count_nonzero(err > t)) for t in (1.0, 2.0)]
    missing = n - int(has.sum())
    return StereoScores(
        judged=n,
        density=float(has.mean()),
        bad1_all=(bad[0] + missing) / n,
        bad2_all=(bad[1] + missing) / n,
        bad1_est=bad[0] / m,
        bad2_est=bad[1] / m,
    )


def evaluate_motorcycle(matcher: StereoMatcher | None = None) -> StereoScores:
    """Run ``matcher`` (default rigkit's SGBM) on Motorcycle and score it."""
    left, right, truth = motorcycle()
    finite = truth[np.isfinite(truth)]
    rng = (int(np.floor(finite.min())) - MARGIN_PX, int(np.ceil(finite.max())) + MARGIN_PX)
    return stereo_scores((matcher or SGBM())(left, right, rng), truth)
