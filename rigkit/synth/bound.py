"""The best any estimator could do: a Cramér–Rao bound on the disparity offset that a
rendered scene's back view gives under the scene's heat shimmer.

The offset is fitted from where the back camera sees points of the left image
(:mod:`rigkit.pipeline.ambiguity`). Heat shimmer moves each frame's image by a smooth
random field, so nearby matches share their errors, and more matches stop adding
information once they are closer together than the shimmer's patches. The renderer's
fields (:mod:`rigkit.synth.shimmer`) have, per axis, the covariance ``rms^2 rho(r)``
between points ``r`` apart (:func:`shimmer_correlation`):

* ``gaussian`` (white noise blurred by a Gaussian of sigma ``c``):
  ``rho = exp(-r^2 / (4 c^2))``;
* ``vonkarman`` (the power spectrum ``(f^2 + 1/L0^2)^(-11/6)``): the Matérn
  correlation of smoothness ``nu = 5/6`` that this spectrum has in two dimensions,
  ``rho = 2^(1-nu) / Gamma(nu) (k r)^nu K_nu(k r)`` with ``k = 2 pi / L0``
  (Rasmussen & Williams, *Gaussian Processes for Machine Learning*, 2006, sec. 4.2.1).

A left/back match's error is the left frame's field at its left pixel plus the back
frame's (an independent draw) at its back pixel - the coarse map between the views is
close to a rotation, which leaves an isotropic field's statistics as they are - plus
the tracker's own independent error. With bursts of N frames per position the
shimmer's part is divided by N: the mean of N independent draws, which the pipeline's
per-pixel median of the frames can only approach (for Gaussian noise the median of 5
has 1.4x the mean's variance), so the bound stays a bound.

Linearised at the pipeline's fit, with that covariance known exactly:

* :attr:`OffsetBound.estimator_px`: how far the pipeline's least-squares offset spreads
  on its own matches (the sandwich covariance of ordinary least squares);
* :attr:`OffsetBound.surface_px`: the same estimator on every point of the surface, on
  a grid finer than the shimmer's patches (what matching everywhere would give);
* :attr:`OffsetBound.bound_px`: the generalised least-squares offset from those points,
  weighted by the exact covariance. For Gaussian errors it is the Cramér–Rao bound:
  no unbiased estimator working from the back view of the frames taken at each
  position has a smaller standard error. The left/right disparity does not help: an
  offset is the one thing it cannot show (the paper's ambiguity).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import cv2
import numpy as np
from scipy.linalg import cho_factor, cho_solve
from scipy.spatial.distance import cdist
from scipy.special import gamma, kv

from rigkit.errors import InputError
from rigkit.pipeline import DepthResult
from rigkit.pipeline.ambiguity import MIN_MATCHES, back_projection
from rigkit.pipeline.rectify import apply_homography
from rigkit.synth.evaluate import visible_in_right
from rigkit.synth.io import SceneTruth

TRACKER_PX = 0.05  # a match's own error per axis, px, independent between matches
GRID_STEP = 0.7  # the dense grid's spacing, in units of the shimmer's correlation length
OUTER_GRID_STEP = 1 / 32  # von Karman: the grid's spacing, in outer scales
# Central-difference steps for beta (rad), the back rotation (rad) and offset (m).
_STEPS = np.array([1e-7, 1e-6, 1e-6, 1e-6, 1e-3, 1e-3])


@dataclass(frozen=True)
class OffsetBound:
    """Standard errors (px of disparity offset) that the frames' shimmer leaves:
    ``estimator_px`` of the pipeline's estimator on its ``matches`` matches,
    ``surface_px`` of that estimator and ``bound_px`` of the best one on
    ``grid_points`` points of the surface."""

    estimator_px: float
    surface_px: float
    bound_px: float
    matches: int
    grid_points: int


Correlation = Callable[[np.ndarray], np.ndarray]
"""One axis of one frame's shimmer: the correlation between two points as a function
of their squared distance (px^2, any shape; may be overwritten)."""


def gaussian_correlation(corr_px: float) -> Correlation:
    """``exp(-r^2 / (4 c^2))``: white noise blurred by a Gaussian of sigma ``corr_px``."""
    scale = -1.0 / (4.0 * corr_px**2)

    def rho(r2: np.ndarray) -> np.ndarray:
        r2 *= scale
        return np.exp(r2, out=r2)

    return rho


VON_KARMAN_NU = 5.0 / 6.0  # (f^2 + 1/L0^2)^(-11/6) = (f^2 + 1/L0^2)^(-(nu + 1)) in 2-D


def vonkarman_correlation(outer_px: float) -> Correlation:
    """The Matérn correlation of the von Karman spectrum of outer scale ``outer_px``
    (module docstring); 1 at distance 0."""
    nu, k = VON_KARMAN_NU, 2 * np.pi / outer_px
    norm = 2 ** (1 - nu) / gamma(nu)

    def rho(r2: np.ndarray) -> np.ndarray:
        x = k * np.sqrt(r2, out=r2)
        with np.errstate(invalid="ignore"):  # 0 * inf at distance 0
            out = norm * x**nu * kv(nu, x)
        out[x == 0] = 1.0
        return out

    return rho


def shimmer_correlation(spectrum: str, corr_px: float, outer_px: float) -> Correlation:
    """The correlation of the renderer's shimmer of ``spectrum`` (``SynthParams``'s
    ``shimmer_spectrum``, ``shimmer_corr_px`` and ``shimmer_outer_px``). Raises
    InputError for the fine spectrum, whose short correlation length would need a grid
    of a few px over the whole image."""
    if spectrum == "gaussian":
        return gaussian_correlation(corr_px)
    if spectrum == "vonkarman":
        return vonkarman_correlation(outer_px)
    raise InputError(f"the bound knows the covariance of gaussian and vonkarman shimmer "
                     f"only, not of {spectrum}")


def shimmer_covariance(
    left_px: np.ndarray,
    back_px: np.ndarray,
    rms_px: float,
    correlation: Correlation,
    tracker_px: float = TRACKER_PX,
    frames: int = 1,
) -> np.ndarray:
    """(N, N) float64 covariance (px^2) of one axis of the errors of N left/back matches
    at left pixels ``left_px`` and back pixels ``back_px`` ((N, 2) px): the two
    positions' shimmer (``rms_px`` per axis and frame, ``correlation`` between points,
    averaged over ``frames`` independent frames) and the tracker's."""
    cov = correlation(cdist(left_px, left_px, "sqeuclidean"))
    cov += correlation(cdist(back_px, back_px, "sqeuclidean"))
    cov *= rms_px**2 / frames
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
    ``result`` on it (on a burst scene, from the stacked bursts: the shimmer is
    averaged over ``truth.params.burst`` frames); ``matches_left_px`` (N, 2): the left
    pixels of the pipeline's left/back matches; ``step_px``: the dense grid's spacing
    (default ``GRID_STEP`` correlation lengths of gaussian shimmer, ``OUTER_GRID_STEP``
    outer scales of von Karman shimmer; memory grows as its inverse 4th power: two N x
    N arrays, ~1.6 GB for 10 000 points). The lens is taken as ideal: on a scene with
    distortion the figures are approximate. Raises InputError for a scene without
    shimmer, with shimmer of the fine spectrum, or with fewer than ``MIN_MATCHES``
    points on its surface."""
    p = truth.params
    if p.shimmer_px <= 0:
        raise InputError(f"{truth.path}: the scene has no heat shimmer to bound the offset by")
    try:
        correlation = shimmer_correlation(p.shimmer_spectrum, p.shimmer_corr_px,
                                          p.shimmer_outer_px)
    except InputError as exc:
        raise InputError(f"{truth.path}: {exc}") from None
    if step_px is None:
        step_px = (OUTER_GRID_STEP * p.shimmer_outer_px if p.shimmer_spectrum == "vonkarman"
                   else GRID_STEP * p.shimmer_corr_px)
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
        return J, shimmer_covariance(left, back, p.shimmer_px, correlation, tracker_px,
                                     frames=max(p.burst, 1))

    def offset_px(covariance: np.ndarray) -> float:
        return f * float(np.sqrt(covariance[0, 0]))

    J, cov = model(matches_left_px)
    estimator, n = offset_px(ols_covariance(J, cov)), len(cov)
    J, cov = model(surface_grid(visible.shape, step_px))
    surface, n_grid = offset_px(ols_covariance(J, cov)), len(cov)
    return OffsetBound(
        estimator_px=estimator,
        surface_px=surface,
        bound_px=offset_px(gls_covariance(J, cov)),
        matches=n,
        grid_points=n_grid,
    )
