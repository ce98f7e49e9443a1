"""Stage 3: removing the disparity ambiguity with the back camera.

The paper (Prop. 2, Alg. 3) takes pairs of same-depth left/back matches and uses
``m_l / m_b = (z + C_lb) / z``; the median over pairs gives the disparity offset. That
ignores the back camera's rotation, which changes local image scale by ~1e-4 across a
6 deg field - comparable to the signal ``C_lb / z`` ~ 0.7 % - and it uses only pairs.

Here every left/back match is used at once, with exact geometry. For a trial yaw
correction ``beta`` of the right camera, each matched left pixel is triangulated from
the dense disparity (:mod:`rigkit.pipeline.depth`), giving a 3D point; the back
camera - centre ``(x_b, y_b, -C_lb)`` with unknown sideways/vertical offset, unknown
rotation, same focal length - must then see it where the match says. ``beta``, the
back rotation and the offsets are fitted jointly by robust least squares. The depth
scale enters through the back view's magnification; the rotation enters through its
projective pattern, so the two do not trade off.

Two things the fit cannot see set the offset's standard error besides the matches'
noise. Heat shimmer moves whole patches of matches together, so a spatial jackknife
measures it. The fit takes every view's principal point at the image centre of the
ideal pixels it is given; the lens stage has fitted each view's own and taken it out
(:mod:`rigkit.pipeline.distortion`): a back view whose principal point sits elsewhere
than the left one's is not a rotation of it (they differ by a gradient of scale ~0.05
px across the frame, the size of the depth signal), and a turn of the back camera
about a misplaced centre magnifies its view (up to ~0.5 % of depth at 40 px; issue
35). What is left of their uncertainty is added as a *consider* term (Schmidt's
consider covariance, as in orbit determination): the offset's sensitivity to a shift
of the back principal point, times its prior spread, which is generous where the
views settled the centres (in shimmer the prior holds them). Estimating the shift in
this fit instead was tried: with clean matches it is recovered, but a single frame's
shimmer leaves it uncertain by more than its prior, and the left view's centre, about
which the back view turns, is not in this fit. One camera moved between the positions
has no shift between its views: there the term is 0, and what the uncertainty of its one
centre carries, the lens stage measures (:attr:`~rigkit.pipeline.distortion.LensFit.
centre_offset_sigma_px`).
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from rigkit.core.lazy import function
from rigkit.errors import PipelineError
from rigkit.geometry import rotvec_to_matrix
from rigkit.pipeline.depth import rectified_rays
from rigkit.pipeline.features import Matches
from rigkit.pipeline.motion import BackStart, back_view_start, spatial_blocks, view_motion
from rigkit.pipeline.rectify import Rectification, apply_homography, plane_slopes, scaling
from rigkit.pipeline.rig import RigGeometry
from rigkit.pipeline.settings import PipelineSettings

least_squares = function("scipy.optimize", "least_squares")

MIN_MATCHES = 30
MAX_BACK_SIDE = 0.5  # back camera's sideways offset, as a fraction of C_lr, still plausible
DEFAULT = PipelineSettings()


@dataclass(frozen=True)
class Ambiguity:
    """Result of ambiguity removal.

    ``beta`` (rad): yaw correction of the right camera; ``offset_px`` ~ ``f * beta``,
    the paper's disparity offset q at the image centre; ``offset_sigma_px``: its
    standard error: the larger of the least-squares one and a spatial jackknife's
    (which also sees errors shared by neighbouring matches, such as heat shimmer),
    combined with ``principal_point_sigma_px``, the part the principal points'
    uncertainty carries, and ``tilt_sigma_px``, the part large-scale shimmer carries
    (:func:`_tilt_beta_sigma`) (where the lens was fitted from the views,
    :func:`~rigkit.pipeline.estimate_depth` adds the part its uncertainty carries,
    :attr:`LensFit.offset_sigma_px`);
    ``back_rotvec`` (3,) left->back rotation (rad); ``back_offset_m``:
    the back camera's fitted (x right, y down) offset from the left optical axis;
    ``matches_used``/``inliers``: left/back matches with a disparity / within 1 px;
    ``rms_px``: reprojection RMS of the inliers in the back view.
    """

    beta: float
    offset_px: float
    offset_sigma_px: float
    back_rotvec: np.ndarray
    back_offset_m: tuple[float, float]
    matches_used: int
    inliers: int
    rms_px: float
    principal_point_sigma_px: float = 0.0
    tilt_sigma_px: float = 0.0

    @property
    def parameters(self) -> np.ndarray:
        """(6,) the fitted parameters in the order :func:`back_projection` takes them:
        ``beta``, the back rotation vector, the back camera's (x, y) offset."""
        return np.concatenate([[self.beta], self.back_rotvec, self.back_offset_m])


def _sample_disparity(
    disparity: np.ndarray, scale: float, rect: Rectification, pts: np.ndarray, edge_window: int
) -> tuple[np.ndarray, np.ndarray]:
    """Rectified full-res column and disparity (full-res px) at left pixels ``pts``.
    Disparities near depth edges or holes (spread over 0.5 px in a window) are NaN."""
    xr = apply_homography(rect.H_left, pts)
    xs = apply_homography(scaling(scale), xr)
    m = xs.astype(np.float32).reshape(-1, 1, 2)
    d = cv2.remap(disparity, m[..., 0], m[..., 1], cv2.INTER_LINEAR, borderValue=np.nan)
    k = np.ones((edge_window, edge_window), np.uint8)
    filled = np.nan_to_num(disparity, nan=-1e6)
    spread = cv2.dilate(filled, k) - cv2.erode(np.nan_to_num(disparity, nan=1e6), k)
    s = cv2.remap(spread, m[..., 0], m[..., 1], cv2.INTER_NEAREST, borderValue=np.inf)
    d = np.where(s.ravel() < 0.5, d.ravel(), np.nan)
    return xr, d / scale


def _rays(rect: Rectification, xr: np.ndarray, d: np.ndarray, beta: float, c_lr: float
          ) -> tuple[np.ndarray, np.ndarray]:
    """Left-frame rays (N, 3) (unit z in the rectified frame) of rectified positions
    ``xr`` (N, 2) with disparities ``d`` (N,), and their inverse depths (N,) (1/m) for
    the yaw correction ``beta``: :func:`~rigkit.pipeline.depth.triangulate_z` as 1/z,
    finite for every disparity (a point beyond infinity has a negative one)."""
    a, b = rectified_rays(rect, xr[:, 0], d)
    t = np.tan(beta)
    w = (a - (b + t) / (1.0 - b * t)) / c_lr
    f = rect.K[0, 0]
    py = (xr[:, 1] - rect.K[1, 2] - rect.canvas[1, 2]) / f
    ray = np.stack([a, py, np.ones_like(a)], axis=1) @ rect.R_rect  # rectified -> left
    return ray, w


def back_projection(
    p: np.ndarray, rect: Rectification, xr: np.ndarray, d: np.ndarray, c_lr: float, c_lb: float
) -> np.ndarray:
    """Where the back camera sees the left points at rectified positions ``xr`` (N, 2)
    with disparities ``d`` (N,) (full-resolution px, ``x_left - x_right``): (N, 2) px,
    ideal pinhole, for parameters ``p`` (:attr:`Ambiguity.parameters`). The point
    ``ray / w`` seen from the back camera's centre ``c`` projects as ``R (ray - w c)``
    (scaled by ``w``), smooth and finite for every ``w``: the fit never meets a point
    that its trial yaw puts beyond infinity as a non-finite residual."""
    ray, w = _rays(rect, xr, d, p[0], c_lr)
    R = rotvec_to_matrix(p[1:4])
    Xb = (ray - w[:, None] * np.array([p[4], p[5], -c_lb])) @ R.T
    K = rect.K
    return Xb[:, :2] / Xb[:, 2:3] * K[0, 0] + K[:2, 2]


def _residuals(p, rect, xr, d, pb, c_lr, c_lb):
    return (back_projection(p, rect, xr, d, c_lr, c_lb) - pb).ravel()


def _initial(start: BackStart, rect: Rectification, xr, d, c_lr: float
             ) -> np.ndarray:
    """The fit's start from ``start`` (the range the back view's magnification implies
    at the matches' mean inverse depth, and its rotation vector;
    :func:`~rigkit.pipeline.motion.back_view_start`): the yaw that gives the matches
    that mean inverse depth (one Newton step from its first-order value; inverse depth
    is nearly linear in the yaw), no sideways or vertical offset."""
    z0, rotvec = start
    a, b = rectified_rays(rect, xr[:, 0], d)
    # 1/z = (a - tan(atan b + beta)) / c_lr ~ (a - b - beta (1 + b^2)) / c_lr
    beta = float((np.mean(a - b) - c_lr / z0) / np.mean(1 + b * b))
    t = np.tan(beta)
    w = (a - (b + t) / (1 - b * t)) / c_lr
    slope = -np.mean((1 + t * t) * (1 + b * b) / (1 - b * t) ** 2) / c_lr  # d mean(w) / d beta
    beta -= float((np.mean(w) - 1.0 / z0) / slope)
    return np.concatenate([[beta], rotvec, [0.0, 0.0]])


def remove_ambiguity(
    matches: Matches,
    disparity: np.ndarray,
    disparity_scale: float,
    rect: Rectification,
    rig: RigGeometry,
    settings: PipelineSettings = DEFAULT,
    start: BackStart | None = None,
) -> Ambiguity:
    """Fit the right camera's yaw correction from left/back ``matches`` (ideal pinhole
    pixels, see :mod:`rigkit.pipeline.lens`) of the ``rig``: its baselines, and whether
    one camera took the views (then no shift between the back and the left principal
    points is carried: :func:`_principal_point_beta_sigma`).

    disparity: (h, w) float32 on the ``disparity_scale``-resized rectified canvas, px,
    ``x_left - x_right``, NaN = unknown. ``start``: where the fit starts, the range
    the back view's magnification implies and its rotation
    (:func:`~rigkit.pipeline.motion.back_view_start` of the rig's motion); None: of
    the back view's motion measured from ``matches`` alone.
    """
    xr, d = _sample_disparity(
        disparity, disparity_scale, rect, matches.left, settings.edge_window_px
    )
    ok = np.isfinite(d)
    if ok.sum() < MIN_MATCHES:
        raise PipelineError(
            f"left/back: only {int(ok.sum())} back-view matches fall on a reliable disparity "
            f"(need {MIN_MATCHES})"
        )
    xr, d, pb = xr[ok], d[ok], matches.other[ok]
    c_lr, c_lb = rig.baseline_lr_m, rig.baseline_lb_m
    if start is None:
        centre = np.array([rect.K[0, 2], rect.K[1, 2]])
        start = back_view_start(view_motion(matches, rect.K[0, 0], centre, "z"), c_lb)
    fit, inl = _fit(start, rect, xr, d, pb, c_lr, c_lb)
    args = (rect, xr[inl], d[inl], pb[inl], c_lr, c_lb)
    jack_sigma = _jackknife_beta_sigma(
        fit.x, args, matches.left[ok][inl], settings.jackknife_blocks
    )
    side = float(fit.x[4])
    if abs(side) > MAX_BACK_SIDE * c_lr:
        # The back camera stands behind the left one. If it fits about C_lr to the
        # side, the "left" image came from the right camera: the parallax is reversed.
        raise PipelineError(
            f"left and right look swapped: the back camera fits {side:+.2f} m to the side "
            f"of the given left camera (expected behind it, C_lr = {c_lr} m)"
        )
    f = rect.K[0, 0]
    noise_sigma = f * max(_least_squares_beta_sigma(fit), jack_sigma)
    apart_px = 0.0 if rig.one_camera else settings.principal_point_sigma * _width(rect)
    pp_sigma = f * _principal_point_beta_sigma(fit, apart_px)
    tilt_sigma = f * _tilt_beta_sigma(fit, pb[inl], rect.K[:2, 2], rect.row_stretch_sq)
    return Ambiguity(
        beta=float(fit.x[0]),
        offset_px=float(f * np.tan(fit.x[0])),
        offset_sigma_px=float(np.sqrt(noise_sigma**2 + pp_sigma**2 + tilt_sigma**2)),
        principal_point_sigma_px=pp_sigma,
        tilt_sigma_px=tilt_sigma,
        back_rotvec=fit.x[1:4].copy(),
        back_offset_m=(float(fit.x[4]), float(fit.x[5])),
        matches_used=int(ok.sum()),
        inliers=int(inl.sum()),
        rms_px=_rms(fit.fun),
    )


def _width(rect: Rectification) -> float:
    """Image width (px) of the views: the assumed principal point is its centre."""
    return 2 * float(rect.K[0, 2]) + 1


def _least_squares_beta_sigma(fit) -> float:
    """Standard error of ``beta`` (rad) from the fit's covariance, every residual
    taken as independent."""
    res = fit.fun
    sigma2 = float(res @ res) / max(res.size - fit.x.size, 1)
    try:
        return float(np.sqrt(np.linalg.inv(fit.jac.T @ fit.jac)[0, 0] * sigma2))
    except np.linalg.LinAlgError:
        return float("inf")


def shift_sensitivity(J: np.ndarray, per_point: int) -> np.ndarray:
    """How a least-squares fit moves when a coordinate is shifted by 1 px at every
    point: (P, per_point), the parameters' change per px of a shift of the ``k``-th
    residual of each point (rows ``k::per_point`` of the (M, P) Jacobian ``J``, M a
    multiple of ``per_point``). To first order a shift ``delta`` moves the fit by
    ``-(J^T J)^-1 J^T G delta``, ``G`` stacking one identity per point; the sign does
    not matter to a consider covariance. Raises LinAlgError where J^T J is singular."""
    G = np.zeros((J.shape[0], per_point))
    for k in range(per_point):
        G[k::per_point, k] = 1.0
    return np.linalg.solve(J.T @ J, J.T @ G)


def _principal_point_beta_sigma(fit, camera_sigma_px: float) -> float:
    """Consider term (rad): the spread of ``beta`` that an unknown shift between the
    back and the left principal points carries, each camera's being ``camera_sigma_px``
    (one standard deviation per axis) from the image centre: a shift moves every
    predicted back position (u, v) by itself (:func:`shift_sensitivity`)."""
    if camera_sigma_px == 0:
        return 0.0
    try:
        sensitivity = shift_sensitivity(fit.jac, 2)[0]  # rad per px of shift
    except np.linalg.LinAlgError:
        return float("inf")
    return float(np.linalg.norm(sensitivity) * np.sqrt(2) * camera_sigma_px)


def _tilt_beta_sigma(fit, back_px: np.ndarray, centre: np.ndarray, stretch_sq: float) -> float:
    """The spread of ``beta`` (rad) that heat shimmer at the scale of the
    whole frame carries. Real turbulence moves an image mostly by large-scale tilt (a
    von Karman spectrum, whose outer scale exceeds the frame); its share that
    magnifies the back view against the left one is exactly what ``beta`` is fitted
    from, so the fit cannot see it, and the block jackknife cannot either (every block
    moves alike). Three other modes of the same air are seen, and they say how large
    the magnification's may be (:func:`magnification_variance`): the right view's
    rows still stretch against the left one's from top to bottom (``stretch_sq``,
    :attr:`Rectification.row_stretch_sq`: two rotations cannot absorb a stretch), and
    the back view's residuals still shear (:func:`residual_shear_sq`: neither its
    pose nor the offset can). The offset's sensitivity to a back-view magnification
    turns that into a spread of ``beta``.

    back_px: (N, 2) the fitted matches' back positions (px), in the order of ``fit``'s
    residuals; ``centre``: (2,) the principal point (px)."""
    shear_sq = residual_shear_sq(back_px, fit.fun.reshape(-1, 2))
    variance = magnification_variance(stretch_sq, shear_sq)
    if variance <= 0:
        return 0.0
    magnified = (back_px - centre).ravel()  # a magnification eps moves each point by this
    try:
        sensitivity = np.linalg.solve(fit.jac.T @ fit.jac, fit.jac.T @ magnified)[0]
    except np.linalg.LinAlgError:
        return float("inf")
    return float(abs(sensitivity) * np.sqrt(variance))


def magnification_variance(stretch_sq: float, shear_sq: float) -> float:
    """The variance (unitless) of the magnification that large-scale shimmer gives
    one view against another, from what else of it two views show: ``stretch_sq``,
    the squared stretch of one axis (phi_yy of the tilt's phase screen phi), and
    ``shear_sq``, the two shears' squares summed ((phi_xx - phi_yy) / 2 and phi_xy).
    For an isotropic phase screen var(phi_yy) = 3c, each shear's variance is c and the
    magnification's, var((phi_xx + phi_yy) / 2), 2c; pooled by their degrees of
    freedom (one, two), c = (stretch_sq / 3 + shear_sq) / 3. One frame shows one draw
    of each mode, and from the stretch alone (1 degree of freedom) the estimate is
    often far below its expectation: in 150 draws of ``rigkit synth``'s air at 1152 px
    the magnification left 2 sigma of this term in 21 % of frames (von Karman) and 24 %
    (Gaussian), pooled in 4 % and 8 %; hidden single frames had reached 3.2 sigma
    (issue 35). (That air draws the two axes independently, not as a phase screen's
    gradient: there both estimates exceed the magnification's variance on average,
    by 1.75x from the stretch alone and 1.95x pooled.)"""
    return 2.0 * (stretch_sq / 3.0 + shear_sq) / 3.0


def residual_shear_sq(px: np.ndarray, residuals: np.ndarray) -> float:
    """The squared shear (unitless) of a residual field: ``residuals`` (N, 2) px at
    ``px`` (N, 2) px, fitted by an affine map by least squares, whose gradient A gives
    the two shears (A_xx - A_yy) / 2 and (A_xy + A_yx) / 2; their squares summed, less
    what the residuals' scatter gives them (0 where that is all). A rotation and a
    magnification of the view, which a camera's pose and the offset absorb, have none."""
    try:
        slopes, variance = plane_slopes(px, residuals)  # (2, 2): [position, component]
    except np.linalg.LinAlgError:
        return 0.0
    A = slopes.T  # A[i, j]: d(residual i) / d(position j)
    shears = (A[0, 0] - A[1, 1]) / 2, (A[0, 1] + A[1, 0]) / 2
    noise = float(variance.sum()) / 4  # each shear is half a sum of two slopes
    return max(shears[0] ** 2 + shears[1] ** 2 - noise, 0.0)


def _jackknife_beta_sigma(
    p: np.ndarray, args: tuple, left_px: np.ndarray, blocks: int
) -> float:
    """Standard error of ``beta`` by the delete-one-block jackknife over a
    ``blocks`` x ``blocks`` grid of the left image (Kuensch 1989's block idea): errors
    that neighbouring matches share - heat shimmer moves whole patches - are invisible
    to the least-squares covariance, which takes every residual as independent.
    left_px: (N, 2) left pixels of the matches in ``args``."""
    label = spatial_blocks(left_px, blocks)
    rect, xr, d, pb, c_lr, c_lb = args
    betas = []
    for b in np.unique(label):
        keep = label != b
        if keep.sum() < MIN_MATCHES:
            continue
        sub = (rect, xr[keep], d[keep], pb[keep], c_lr, c_lb)
        betas.append(least_squares(_residuals, p, args=sub, x_scale=_SCALES, max_nfev=20).x[0])
    n = len(betas)
    if n < 2:
        return 0.0
    return float(np.sqrt((n - 1) / n * np.sum((np.array(betas) - np.mean(betas)) ** 2)))


def _rms(res: np.ndarray) -> float:
    """RMS reprojection distance (px) of stacked (u, v) residuals."""
    return float(np.sqrt(np.mean(res**2) * 2))


_SCALES = np.array([1e-4, 1e-3, 1e-3, 1e-3, 0.1, 0.1])  # typical sizes of the parameters


def _fit(start: BackStart, rect, xr, d, pb, c_lr: float, c_lb: float):
    """Robust fit of (beta, back rotation, back offset) from ``start`` (:func:`_initial`);
    returns (final fit on the inliers, inlier mask over the given matches)."""
    args = (rect, xr, d, pb, c_lr, c_lb)
    p0 = _initial(start, rect, xr, d, c_lr)
    fit = least_squares(_residuals, p0, args=args, x_scale=_SCALES)
    # A redescending loss: a wrong disparity moves a point in the back view by little,
    # so outliers are small and a bounded-influence (L1-like) loss would still be biased.
    fit = least_squares(_residuals, fit.x, args=args, loss="cauchy", f_scale=0.2, x_scale=_SCALES)
    err = np.linalg.norm(_residuals(fit.x, *args).reshape(-1, 2), axis=1)
    inl = err < 3.0 * 1.4826 * float(np.median(err))
    if inl.sum() < MIN_MATCHES:
        raise PipelineError(
            f"left/back: only {int(inl.sum())} matches agree with one back-camera pose"
        )
    args = (rect, xr[inl], d[inl], pb[inl], c_lr, c_lb)
    return least_squares(_residuals, fit.x, args=args, x_scale=_SCALES), inl
