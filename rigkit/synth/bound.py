"""The best any estimator could do: a Cramér–Rao bound on the disparity offset that a
rendered scene's back view gives under the scene's heat shimmer.

The offset is fitted from where the back camera sees points of the left image
(:mod:`rigkit.pipeline.ambiguity`). Heat shimmer moves each frame's image by a smooth
random field, so nearby matches share their errors, and more matches stop adding
information once they are closer together than the shimmer's patches. The renderer's
field (:func:`rigkit.synth.shimmer.shimmer_field`, white noise blurred by a Gaussian of
sigma ``c``) has, per axis, the covariance ``rms^2 exp(-r^2 / (4 c^2))`` between points
``r`` apart. A left/back match's error is the left frame's field at its left pixel plus
the back frame's (an independent draw) at its back pixel - the coarse map between the
views is close to a rotation, which leaves an isotropic field's statistics as they
are - plus the tracker's own independent error.

Linearised at the pipeline's fit, with that covariance known exactly:

* :attr:`OffsetBound.estimator_px`: how far the pipeline's least-squares offset spreads
  on its own matches (the sandwich covariance of ordinary least squares);
* :attr:`OffsetBound.surface_px`: the same estimator on every point of the surface, on
  a grid finer than the shimmer's patches (what matching everywhere would give);
* :attr:`OffsetBound.bound_px`: the generalised least-squares offset from those points,
  weighted by the exact covariance. For Gaussian errors it is
  the Cramér–Rao bound: no unbiased estimator working from the back view of one frame
  per position has a smaller standard error. The left/right disparity does not help:
  an offset is the one thing it cannot show (the paper's ambiguity).
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np
from scipy.linalg import cho_factor, cho_solve
from scipy.spatial.distance import cdist

from rigkit.errors import InputError
from rigkit.pipeline import DepthResult
from rigkit.pipeline.ambiguity import MIN_MATCHES, back_projection
from rigkit.pipeline.rectify import apply_homography
from rigkit.synth.evaluate import visible_in_right
from rigkit.synth.io import SceneTruth

TRACKER_PX = 0.05  # a match's own error per axis, px, independent between matches
GRID_STEP = 0.7  # the dense grid's spacing, in units of the shimmer's correlation length
# Central-difference steps for beta (rad), the back rotation (rad) and offset (m).
_STEPS = np.array([1e-7, 1e-6, 1e-6, 1e-6, 1e-3, 1e-3])


@dataclass(frozen=True)
class OffsetBound:
    """Standard errors (px of disparity offset) that one frame's shimmer leaves:
    ``estimator_px`` of the pipeline's estimator on its ``matches`` matches,
    ``surface_px`` of that estimator and ``bound_px`` of the best one on
    ``grid_points`` points of the surface."""

    estimator_px: float
    surface_px: float
    bound_px: float
    matches: int
    grid_points: int


def shimmer_covariance(
    left_px: np.ndarray,
    back_px: np.ndarray,
    rms_px: float,
    corr_px: float,
    tracker_px: float = TRACKER_PX,
) -> np.ndarray:
    """(N, N) float64 covariance (px^2) of one axis of the errors of N left/back matches
    at left pixels ``left_px`` and back pixels ``back_px`` ((N, 2) px): the two frames'
    shimmer (``rms_px`` per axis, Gaussian blur sigma ``corr_px``) and the tracker's."""
    scale = -1.0 / (4.0 * corr_px**2)
    cov = cdist(left_px, left_px, "sqeuclidean")
    cov *= scale
    np.exp(cov, out=cov)
    other = cdist(back_px, back_px, "sqeuclidean")
    other *= scale
    cov += np.exp(other, out=other)
    del other
    cov *= rms_px**2
    cov[np.diag_indices_from(cov)] += tracker_px**2
    return cov


def gls_covariance(J: np.ndarray, cov: np.ndarray) -> np.ndarray:
    """(P, P) covariance of the generalised least-squares estimate of a linear model
    with Jacobian ``J`` (2N, P), rows (u, v) of each point in turn, whose u and v errors
    are independent with the same (N, N) covariance ``cov``. Overwrites ``cov``."""
    factor = cho_factor(cov, overwrite_a=True)
    info = sum(J[a::2].T @ cho_solve(factor, J[a::2]) for a in range(2))
    return np.linalg.inv(info)


def ols_covariance(J: np.ndarray, cov: np.ndarray) -> np.ndarray:
    """(P, P) covariance of the ordinary least-squares estimate for the model of
    :func:`gls_covariance` (the sandwich: it is not the covariance OLS reports)."""
    bread = np.linalg.inv(J.T @ J)
    meat = sum(J[a::2].T @ cov @ J[a::2] for a in range(2))
    return bread @ meat @ bread


def back_view_jacobian(
    params: np.ndarray, truth: SceneTruth, result: DepthResult, xr: np.ndarray, d: np.ndarray
) -> np.ndarray:
    """(2N, 6) derivatives of the back-view positions of the points (rectified ``xr``
    (N, 2), disparity ``d`` (N,), px) by the ambiguity fit's ``params``, by central
    differences."""
    args = (result.rectification, xr, d, truth.baseline_lr_m, truth.baseline_lb_m)
    J = np.empty((2 * len(xr), len(params)))
    for k, step in enumerate(_STEPS):
        e = np.zeros(len(params))
        e[k] = step
        up, down = back_projection(params + e, *args), back_projection(params - e, *args)
        J[:, k] = (up - down).ravel() / (2 * step)
    return J


def exact_tracks(
    truth: SceneTruth, result: DepthResult, left_px: np.ndarray, visible: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Where the true cameras see the surface behind left pixels ``left_px`` (N, 2):
    (kept left pixels (M, 2), their rectified positions (M, 2), true disparities (M,)
    through the pipeline's rectification, back pixels (M, 2)), for those the right
    camera sees (``visible``, (H, W) bool) and that land inside the back image."""
    if len(left_px) == 0:
        return left_px, left_px, np.empty(0), left_px
    cams = truth.cameras
    grid = left_px.astype(np.float32).reshape(-1, 1, 2)
    z = cv2.remap(truth.depth("left"), grid[..., 0], grid[..., 1], cv2.INTER_NEAREST,
                  borderValue=np.nan).ravel().astype(np.float64)
    seen = cv2.remap(visible.astype(np.uint8), grid[..., 0], grid[..., 1], cv2.INTER_NEAREST)
    X = cams["left"].C + z[:, None] * cams["left"].rays(left_px[:, 0], left_px[:, 1])
    back = cams["back"].project(X)[0]
    right = cams["right"].project(X)[0]
    w, h = cams["back"].width, cams["back"].height
    keep = (seen.ravel() > 0) & np.isfinite(back).all(axis=1) & np.isfinite(right).all(axis=1)
    keep &= (back[:, 0] >= 0) & (back[:, 0] <= w - 1) & (back[:, 1] >= 0) & (back[:, 1] <= h - 1)
    rect = result.rectification
    xr = apply_homography(rect.H_left, left_px[keep])
    d = xr[:, 0] - apply_homography(rect.H_right, right[keep])[:, 0]
    return left_px[keep], xr, d, back[keep]


def surface_grid(shape: tuple[int, int], step_px: float) -> np.ndarray:
    """(N, 2) px: a square grid of ``step_px`` over an (H, W) image, cell centres."""
    v, u = np.mgrid[step_px / 2 : shape[0] : step_px, step_px / 2 : shape[1] : step_px]
    return np.stack([u.ravel(), v.ravel()], axis=1)


def offset_bound(
    truth: SceneTruth,
    result: DepthResult,
    matches_left_px: np.ndarray,
    step_px: float | None = None,
    tracker_px: float = TRACKER_PX,
) -> OffsetBound:
    """:class:`OffsetBound` of a rendered scene (``truth``) and the pipeline's
    ``result`` on its first frames; ``matches_left_px`` (N, 2): the left pixels of the
    pipeline's left/back matches; ``step_px``: the dense grid's spacing (default
    ``GRID_STEP`` shimmer correlation lengths; memory grows as its inverse 4th power:
    two N x N arrays, ~1.6 GB for 10 000 points). The lens is taken as ideal: on a
    scene with distortion the figures are approximate. Raises InputError for a scene
    without shimmer, with shimmer of another spectrum than gaussian, or with fewer than
    ``MIN_MATCHES`` points on its surface."""
    rms, corr = truth.params.shimmer_px, truth.params.shimmer_corr_px
    if rms <= 0:
        raise InputError(f"{truth.path}: the scene has no heat shimmer to bound the offset by")
    if truth.params.shimmer_spectrum != "gaussian":
        raise InputError(f"{truth.path}: the bound knows the covariance of gaussian shimmer "
                         f"only, not of {truth.params.shimmer_spectrum}")
    params = result.ambiguity.parameters
    f = result.rectification.K[0, 0]
    visible = visible_in_right(truth)

    def model(points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(Jacobian, covariance) of the points of ``points`` on the surface."""
        left, xr, d, back = exact_tracks(truth, result, points, visible)
        if len(left) < MIN_MATCHES:
            raise InputError(
                f"{truth.path}: only {len(left)} points on the surface to bound the offset "
                f"with (need {MIN_MATCHES}; a finer grid step?)"
            )
        J = back_view_jacobian(params, truth, result, xr, d)
        return J, shimmer_covariance(left, back, rms, corr, tracker_px)

    def offset_px(covariance: np.ndarray) -> float:
        return f * float(np.sqrt(covariance[0, 0]))

    J, cov = model(matches_left_px)
    estimator, n = offset_px(ols_covariance(J, cov)), len(cov)
    J, cov = model(surface_grid(visible.shape, step_px or GRID_STEP * corr))
    surface, n_grid = offset_px(ols_covariance(J, cov)), len(cov)
    return OffsetBound(
        estimator_px=estimator,
        surface_px=surface,
        bound_px=offset_px(gls_covariance(J, cov)),
        matches=n,
        grid_points=n_grid,
    )
