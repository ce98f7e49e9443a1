"""The paper's method as section 4 writes it, to compare with on our scenes.

* Pseudo-rectification (Alg. 2): RANSAC over samples of ``M`` matches for the second
  rows of two affine warps, ``<H_l[1], x_l> = <H_r[1], x_r>`` with ``H_l[1, 2] = 0``,
  solved as a homogeneous system by SVD and scaled to ``|H_l[1, :2]| = 1``,
  ``H_l[1, 1] > 0``; inliers within ``eps`` px. The first rows follow from the norm and
  determinant constraints: ``H[0, :2] = (H[1, 1], -H[1, 0])``, so the left warp is rigid.
* The stereo matcher on the warped pair (rigkit's SGBM; the paper used HSM).
* Ambiguity removal (Alg. 3, Prop. 2): random pairs of left/back matches; a pair with
  ``m_l > m_b``, ``m_l > delta`` and ``|d_1 - d_2| < eta`` gives the offset
  ``q = f C_lr / C_lb (m_l / m_b - 1) - (d_1 + d_2) / 2``; the median is taken.
* Depth ``z = f C_lr / (d + q)`` (Eq. 5) at every left pixel.

``delta`` and ``eta`` are the paper's 300 px and 3 px at 4608 px wide images, scaled
with the image width for smaller renders (see docs/experiments.md).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from rigkit.errors import PipelineError
from rigkit.experiments.common import (
    RectifiedPair,
    dense_disparity,
    left_grid,
    on_canvas,
    sample_disparity,
)
from rigkit.pipeline.features import Matches
from rigkit.pipeline.stereo import StereoMatcher

PAPER_WIDTH = 4608  # px: the width at which the paper's thresholds are given


@dataclass(frozen=True)
class PaperSettings:
    """The paper's hyper-parameters (sec. 5.2), px at a 4608 px wide image."""

    sample_size: int = 10  # M
    epsilon_px: float = 2.0
    trials: int = 2000  # T of Alg. 2 (not given in the paper)
    delta_px: float = 300.0
    eta_px: float = 3.0
    pair_trials: int = 20000  # T of Alg. 3 (not given in the paper)


def _row_system(pl: np.ndarray, pr: np.ndarray) -> np.ndarray:
    """Rows ``[u_l, v_l, -u_r, -v_r, -1]`` of the equal-row equation (N, 5)."""
    return np.column_stack([pl, -pr, -np.ones(len(pl))])


def _solve_rows(A: np.ndarray) -> np.ndarray | None:
    """SVD null vector, scaled so that |(h_l21, h_l22)| = 1 and h_l22 > 0."""
    x = np.linalg.svd(A)[2][-1]
    n = float(np.hypot(x[0], x[1]))
    if n < 1e-12:
        return None
    x = x / n
    return -x if x[1] < 0 else x


def affine_rows_ransac(
    pl: np.ndarray, pr: np.ndarray, settings: PaperSettings, rng: np.random.Generator
) -> tuple[np.ndarray, np.ndarray]:
    """RANSAC of Alg. 2, steps 3-7, on matches ``pl`` <-> ``pr`` ((N, 2) px each).

    Returns ((5,) = (h_l21, h_l22, h_r21, h_r22, h_r23), (N,) bool inliers)."""
    A = _row_system(pl, pr)
    best, best_in = None, np.zeros(len(pl), bool)
    for _ in range(settings.trials):
        pick = rng.choice(len(pl), settings.sample_size, replace=False)
        x = _solve_rows(A[pick])
        if x is None:
            continue
        inl = np.abs(A @ x) < settings.epsilon_px
        if inl.sum() > best_in.sum():
            best, best_in = x, inl
    if best is None or best_in.sum() < settings.sample_size:
        raise PipelineError("paper: no affine pseudo-rectification found by RANSAC")
    return best, best_in


def affine_warps(rows: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The two (3, 3) affine warps from the second-row parameters (step 8)."""
    a, b, c, d, e = rows
    H_l = np.array([[b, -a, 0.0], [a, b, 0.0], [0, 0, 1]])
    H_r = np.array([[d, -c, 0.0], [c, d, e], [0, 0, 1]])
    return H_l, H_r


def pseudo_rectify(
    m_lr: Matches, image_size: tuple[int, int], settings: PaperSettings, rng: np.random.Generator
) -> RectifiedPair:
    """Alg. 2 on left/right matches, onto a canvas; see the module docstring."""
    rows, inl = affine_rows_ransac(m_lr.left, m_lr.other, settings, rng)
    H_l, H_r = affine_warps(rows)
    return on_canvas(H_l, H_r, image_size, m_lr.left[inl], m_lr.other[inl])


def pair_median_offset(
    m_lb: Matches,
    disparity: np.ndarray,
    pair: RectifiedPair,
    f_px: float,
    c_lr: float,
    c_lb: float,
    settings: PaperSettings,
    width: int,
    rng: np.random.Generator,
) -> tuple[float, int]:
    """Alg. 3: the disparity offset q (px) and how many pairs voted for it.

    disparity: from :func:`dense_disparity` (full-resolution px). ``m_lr`` is measured
    in the rectified left view (the paper matches the rectified left image to the back
    image), ``m_b`` in the back image.
    """
    xr, d = sample_disparity(disparity, pair.H_left, m_lb.left)
    ok = np.isfinite(d)
    if ok.sum() < 2:
        raise PipelineError("paper: fewer than 2 left/back matches have a disparity")
    xr, d, pb = xr[ok], d[ok], m_lb.other[ok]
    i, j = rng.integers(len(d), size=(2, settings.pair_trials))
    ml = np.linalg.norm(xr[i] - xr[j], axis=1)
    mb = np.linalg.norm(pb[i] - pb[j], axis=1)
    k = width / PAPER_WIDTH
    use = (ml > mb) & (ml > settings.delta_px * k) & (np.abs(d[i] - d[j]) < settings.eta_px * k)
    if not use.any():
        raise PipelineError("paper: no pair of left/back matches meets the conditions of Alg. 3")
    with np.errstate(divide="ignore"):
        q = f_px * c_lr / c_lb * (ml[use] / mb[use] - 1) - (d[i][use] + d[j][use]) / 2
    return float(np.median(q)), int(use.sum())


def depth_from_offset(
    disparity: np.ndarray, pair: RectifiedPair, q: float, f_px: float, c_lr: float,
    shape: tuple[int, int],
) -> np.ndarray:
    """Eq. 5, ``z = f C_lr / (d + q)``, at every original left pixel: (H, W) float32 m,
    NaN where there is no disparity or the result is not in front of the camera."""
    _, d = left_grid(disparity, pair.H_left, shape)
    with np.errstate(divide="ignore", invalid="ignore"):
        z = f_px * c_lr / (d.astype(np.float64) + q)
    return np.where(z > 0, z, np.nan).astype(np.float32)


def paper_depth(
    left: np.ndarray,
    right: np.ndarray,
    m_lr: Matches,
    m_lb: Matches,
    f_px: float,
    c_lr: float,
    c_lb: float,
    rng: np.random.Generator,
    settings: PaperSettings | None = None,
    matcher: StereoMatcher | None = None,
) -> np.ndarray:
    """Depth of the left view (H, W) float32, metres, by the paper's section 4.

    left, right: (H, W) float32 grey; m_lr, m_lb: left/right and left/back matches.
    Raises PipelineError where a step finds nothing.
    """
    settings = settings or PaperSettings()
    size = (left.shape[1], left.shape[0])
    pair = pseudo_rectify(m_lr, size, settings, rng)
    disparity = dense_disparity(left, right, pair, matcher)
    q, _ = pair_median_offset(
        m_lb, disparity, pair, f_px, c_lr, c_lb, settings, left.shape[1], rng
    )
    return depth_from_offset(disparity, pair, q, f_px, c_lr, left.shape)

