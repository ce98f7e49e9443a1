"""Stage 0b: the lens distortion, fitted from the three views themselves.

RAW frames are not distortion-corrected, and a telephoto lens bends its image by a
fraction of a percent towards the corner. Uncorrected, that bend becomes a smooth
disparity error of several pixels (the same scene point lands ~1000 px apart in the
left and right images of a rig turned by 1 deg) and a wrong back-view magnification:
depth errors of percents. The three views are taken through one lens (or identical
ones), and the rotations between them that make its bend harmful also make it
observable - the same idea as self-calibrating distortion from image matches
(Fitzgibbon, CVPR 2001; Kukelova and Pajdla, radial distortion in minimal problems).

Here it is a small bundle adjustment (:mod:`rigkit.pipeline.bundle`) over the corners
tracked into both other views (:mod:`rigkit.pipeline.features` tracks the same left
corners into each): every track has one unknown inverse depth; the right camera has a
rotation and a baseline direction in the image plane (length C_lr), the back camera a
rotation and a sideways/vertical offset (C_lb behind); the lens has radial terms ``k1``
(and ``k2``), measured about the image centre like :class:`~rigkit.pipeline.lens.Lens`. The
right-camera yaw and the depths trade off (the paper's disparity ambiguity); the back
view's magnification settles them, as in :mod:`rigkit.pipeline.ambiguity`, so the
radial terms are fitted against a full three-view geometry. A given distortion (a
profile, ``camera.distortion``) is the starting point, refined in k1 and k2
(:func:`refine_lens`); tangential terms and ``k3`` are kept as given unless the views
reject the given lens. The fitted lens replaces the given one only where the views
rule it out (:func:`~rigkit.pipeline.covariance.significant_change`): heat shimmer and
principal points apart move the fit even when the given lens is right.

Three cameras are not centred alike (principal points up to ~40 px from the image
centre), and that matters with no bend at all: the back camera is turned by a degree
or so against the left one, and a turn taken about a point ``delta`` px from the true
principal point magnifies the view by about 1.5 * turn (rad) * delta / f, which is
the back view's depth signal itself (1 deg about 40 px off: ~0.35 % of depth at
300 m, lens or none). A bend adds a mismatch of its own (a 6 px corner bend, centres
~40 px apart: ~0.25 px). Each view's centre is therefore fitted (:func:`_fit_centres`),
held by a prior of ``principal_point_sigma`` (of the image width) to the principal
point the rig profile gives, else to the image centre; one camera moved between the
positions has one centre, fitted once (:class:`~rigkit.pipeline.bundle.Centres`). The
later stages take each view's out with its bend (:attr:`LensFit.centres_px`,
:class:`Lens`), so that the back view's turn is about its true centre and a shift of
it moves no depth.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from rigkit.core.lazy import function
from rigkit.geometry import Distortion, distort
from rigkit.pipeline.ambiguity import shift_sensitivity, spatial_blocks
from rigkit.pipeline.bundle import (
    Centres,
    Problem,
    bounds,
    corner_radius,
    initial,
    plain_jacobian,
)
from rigkit.pipeline.covariance import cluster_covariance, significant_change
from rigkit.pipeline.features import Matches
from rigkit.pipeline.lens import Lens
from rigkit.pipeline.motion import BackStart, back_view_start, rig_motion
from rigkit.pipeline.rectify import Rectification, pseudo_rectify
from rigkit.pipeline.rig import CENTRED, RigGeometry
from rigkit.pipeline.settings import PipelineSettings

least_squares = function("scipy.optimize", "least_squares")

MIN_TRACKS = 50
MAX_TRACKS = 1500  # enough for two global terms; the cost grows with the tracks
LOSS_SCALE_PX = 0.3  # residual where the robust loss starts to discount a track
SIGNIFICANCE = 0.997  # the fit replaces the given lens only where the views rule it out
# at this confidence (a chi-square test on the terms, as for 3 sigma on one of them)
MAX_CENTRE_SIGMAS = 4.0  # a view's centre stays within this many prior sigmas of the image's


@dataclass(frozen=True)
class LensFit:
    """Result of :func:`fit_distortion`.

    ``distortion``: the lens to use, OpenCV ``k1, k2, p1, p2, k3`` (normalised
    coordinates about the image centre): ``fitted`` where the views rule out the
    ``start`` it began from (``significant``: a chi-square test of the terms' change
    at ``SIGNIFICANCE``), otherwise ``start``; ``corner_px``: how far the
    fitted lens moves the image corner radially (px, + outwards), with its standard
    error ``corner_sigma_px`` (the tracks' noise and the principal points'
    uncertainty), its part from the noise alone ``corner_noise_sigma_px``, and the
    start's ``start_corner_px``; ``offset_sigma_px``:
    the disparity offset's standard error that the lens's uncertainty carries (px,
    added to the back camera's); ``tracks``: corners seen in all three views that the
    fit used; ``rms_px``: their reprojection RMS; ``start_rejected``: the views ruled
    out the given lens and this is the fit from no distortion (:func:`refine_lens`);
    ``centres_px``: ((x, y) left, right, back) px from the image centre to each view's
    principal point, its centre of distortion (fitted under the prior, else the rig's);
    ``centre_offset_sigma_px``: the disparity offset's standard error that one
    camera's shared centre carries (px; :func:`_shared_centre_offset_sigma`; for three
    cameras the ambiguity stage carries the centres' prior instead, and this is 0).
    """

    distortion: Distortion
    start: Distortion
    fitted: Distortion
    significant: bool
    corner_px: float
    corner_sigma_px: float
    start_corner_px: float
    offset_sigma_px: float
    tracks: int
    rms_px: float
    corner_noise_sigma_px: float
    start_rejected: bool = False
    centres_px: tuple[tuple[float, float], ...] = CENTRED
    centre_offset_sigma_px: float = 0.0

    def lens(self, focal_px: float, size: tuple[int, int], view: int) -> Lens:
        """The :class:`Lens` of view ``view`` (0 left, 1 right, 2 back) to use."""
        return Lens(focal_px, size, self.distortion, self.centres_px[view])

    def warning(self) -> str | None:
        """One line where the views rejected the given lens, else None."""
        if not self.start_rejected:
            return None
        return (
            f"the given lens distortion does not fit these frames: it moves the image "
            f"corner by {self.start_corner_px:+.1f} px, the three views say "
            f"{self.corner_px:+.1f} +- {self.corner_sigma_px:.1f} px; the lens was fitted "
            "from the views instead (check the lens profile and its focal length)"
        )

    def as_dict(self) -> dict[str, object]:
        return {
            "k1_k2_p1_p2_k3": list(self.distortion),
            "start_k1_k2_p1_p2_k3": list(self.start),
            "fitted_k1_k2_p1_p2_k3": list(self.fitted),
            "significant": self.significant,
            "corner_shift_px": _number(self.corner_px),
            "corner_shift_sigma_px": _number(self.corner_sigma_px),
            "corner_shift_noise_sigma_px": _number(self.corner_noise_sigma_px),
            "start_corner_shift_px": _number(self.start_corner_px),
            "offset_sigma_px": _number(self.offset_sigma_px),
            "tracks": self.tracks,
            "reprojection_rms_px": _number(self.rms_px),
            "start_rejected": self.start_rejected,
            "centres_px": {view: [round(c, 2) for c in centre]
                           for view, centre in zip(("left", "right", "back"), self.centres_px,
                                                   strict=True)},
            "centre_offset_sigma_px": _number(self.centre_offset_sigma_px),
        }


def _number(value: float) -> float | None:
    """For JSON: rounded, None where not a finite number (no fit)."""
    return round(value, 4) if np.isfinite(value) else None


def three_view_tracks(m_lr: Matches, m_lb: Matches
                      ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Left corners matched in both other views: (left, right, back), each (N, 2)
    float64 recorded px. Both match sets track the same left corners, so a track is a
    left position present in both."""
    key_r = m_lr.left[:, 0] + 1j * m_lr.left[:, 1]
    key_b = m_lb.left[:, 0] + 1j * m_lb.left[:, 1]
    _, ir, ib = np.intersect1d(key_r, key_b, assume_unique=False, return_indices=True)
    return m_lr.left[ir], m_lr.other[ir], m_lb.other[ib]


def corner_shift_px(lens: Lens) -> float:
    """How far ``lens`` moves the image corner along the radius (px, + outwards)."""
    rc = corner_radius(lens)
    x = rc / np.sqrt(1 + (lens.size[1] / lens.size[0]) ** 2)
    y = x * lens.size[1] / lens.size[0]
    xd, yd = distort(np.array(x), np.array(y), lens.distortion)
    return float((np.hypot(xd, yd) - rc) * lens.focal_px)


def fit_distortion(
    m_lr: Matches, m_lb: Matches, rect: Rectification, lens: Lens, rig: RigGeometry,
    settings: PipelineSettings, start: BackStart | None = None,
) -> LensFit:
    """Refine ``lens``'s radial terms (``settings.distortion_terms``: 1 = k1, 2 = k1 and
    k2) from the left/right and left/back matches (recorded px) of the ``rig``. ``rect``
    is a rectification of the pair under ``lens``, used only as the starting rotation.
    With fewer than ``MIN_TRACKS`` corners seen in all three views the given lens is
    kept (``tracks`` says how many; ``corner_sigma_px`` is infinite).

    ``settings.principal_point_sigma`` (of the image width, one standard deviation per
    axis): how far each view's principal point may sit from the rig's
    (:attr:`RigGeometry.principal_points_px`). A right or back view whose principal
    point differs from the left one's bends the tracks like a lens would (the fit's
    bend was 1-16 % off with +-30 px between views); the standard errors include that,
    as a consider term (see :mod:`rigkit.pipeline.ambiguity`); whether the fit is taken
    depends on the noise part alone. ``settings.jackknife_blocks``: spatial blocks per
    image side for the noise part's cluster-robust estimate (:func:`_lens_sigmas`).
    ``start``: the range and back rotation the bundle starts from
    (:func:`~rigkit.pipeline.motion.back_view_start`); None: of the tracks' motion."""
    terms = _fit_terms(m_lr, m_lb, rect, lens, rig, settings, settings.distortion_terms, start)
    return terms.centred()


@dataclass(frozen=True)
class _TermsFit:
    """The first phase of :func:`fit_distortion`: the radial terms fitted and judged
    (``result``, every view bent about the image centre), with what the second phase,
    each view's own centre (:meth:`centred`), starts from. ``problem`` is None where
    there was nothing to fit."""

    result: LensFit
    centres: Centres
    problem: Problem | None = None
    x: np.ndarray | None = None
    opts: dict | None = None
    inflation: float = float("inf")
    prior_px: float = 0.0
    blocks: int = 4

    def centred(self) -> LensFit:
        """The result with each view's own centre (one camera's, shared), fitted with
        the terms where the fit is taken, under the given terms where those stand (no
        bend included); the rig's where no prior lets them move."""
        r, problem = self.result, self.problem
        if (problem is None or self.x is None or self.opts is None
                or self.prior_px <= 0 or not np.isfinite(self.inflation)):
            return r
        n = problem.n_terms
        start = self.x.copy()
        if not r.significant:
            start[:n] = 0.0
        x, q = _fit_centres(problem, start, self.opts, self.centres, self.prior_px,
                            self.inflation, self.blocks, 0 if r.significant else n)
        centres = self.centres.at(q)
        centred = replace(r, centres_px=tuple((float(u), float(v)) for u, v in centres),
                          centre_offset_sigma_px=_shared_centre_offset_sigma(
                              problem, x, self.centres, self.prior_px))
        if not r.significant:
            return centred
        fitted = problem.distortion(x)
        lens = problem.lens
        return replace(centred, distortion=fitted, fitted=fitted,
                       corner_px=corner_shift_px(Lens(lens.focal_px, lens.size, fitted)))


def _fit_terms(
    m_lr: Matches, m_lb: Matches, rect: Rectification, lens: Lens, rig: RigGeometry,
    settings: PipelineSettings, n_terms: int, start: BackStart | None = None,
) -> _TermsFit:
    """``n_terms`` radial terms of :func:`fit_distortion` fitted and judged, every view
    bent about the rig's principal point for it."""
    centres = Centres.of(rig.principal_points_px, rig.one_camera)
    given = tuple((float(u), float(v)) for u, v in centres.given)
    pl, pr, pb = three_view_tracks(m_lr, m_lb)
    if len(pl) < MIN_TRACKS:
        # Too little seen by all three views to tell: keep the given lens, and say so.
        corner = corner_shift_px(lens)
        return _TermsFit(LensFit(lens.distortion, lens.distortion, lens.distortion, False,
                                 corner, float("inf"), corner, 0.0, len(pl), float("nan"),
                                 float("inf"), centres_px=given), centres)
    keep = np.unique(np.linspace(0, len(pl) - 1, min(len(pl), MAX_TRACKS)).astype(int))
    tracks = (pl[keep], pr[keep], pb[keep])
    c_lr, c_lb = rig.baseline_lr_m, rig.baseline_lb_m
    if start is None:
        _, back = rig_motion(m_lr, m_lb, lens.focal_px, lens.centre, (pl, pr, pb))
        start = back_view_start(back, c_lb)
    z0, back_rotvec = start
    problem = Problem(lens, tracks, c_lr, c_lb, n_terms, 1.0 / z0, centres.given)
    p0 = initial(problem, rect, back_rotvec)
    scales = np.array([1e-3] * (n_terms + 7) + [0.1, 0.1])
    # The Jacobian of the depths solved for inside (variable projection), not finite
    # differences of a depth solve per column (Problem.jacobian)
    opts = dict(x_scale=scales, jac=problem.jacobian, method="trf",
                bounds=bounds(p0, n_terms, c_lb))
    fit = least_squares(problem.residuals, p0, **opts)
    fit = least_squares(problem.residuals, fit.x, loss="cauchy", f_scale=LOSS_SCALE_PX, **opts)
    fitted = problem.distortion(fit.x)
    prior_px, blocks = settings.principal_point_sigma * lens.size[0], settings.jackknife_blocks
    # Views that share one centre do not bend apart: no consider term for the lens.
    apart_px = 0.0 if rig.one_camera else prior_px
    corner_sigma, noise_sigma, offset_sigma, cov, inflation = _lens_sigmas(
        fit.x, problem, lens, apart_px, blocks
    )
    err = np.linalg.norm(problem.residuals(fit.x).reshape(-1, 2), axis=1)
    # Noise in the tracks (heat shimmer above all) and the views' unknown principal
    # points move the fit even when the given lens is right: a change the views cannot
    # tell from them is not taken (on field scenes without distortion, weighing the
    # noise alone at 2 sigma took a lens in 4 of 9 runs and biased depth by 0.7 %).
    significant = significant_change(fit.x[:n_terms], cov, SIGNIFICANCE)
    result = LensFit(
        distortion=fitted if significant else lens.distortion,
        start=lens.distortion,
        fitted=fitted,
        significant=significant,
        corner_px=corner_shift_px(Lens(lens.focal_px, lens.size, fitted)),
        corner_sigma_px=corner_sigma,
        offset_sigma_px=offset_sigma,
        start_corner_px=corner_shift_px(lens),
        tracks=len(tracks[0]),
        rms_px=float(np.sqrt(np.mean(err[err < 3.0] ** 2))),
        corner_noise_sigma_px=noise_sigma,
        centres_px=given,
    )
    return _TermsFit(result, centres, problem, fit.x, opts, inflation, prior_px, blocks)


def _fit_centres(
    problem: Problem, x: np.ndarray, opts: dict, centres: Centres, prior_px: float,
    inflation: float, blocks: int, fixed_terms: int = 0,
) -> tuple[np.ndarray, np.ndarray]:
    """The fit again from ``x`` with the views' centres free as ``centres`` lets them
    move, each held to the rig's by a Gaussian prior of ``prior_px`` (one standard
    deviation per axis), the first ``fixed_terms`` radial terms held as they are in
    ``x``: the outer parameters (P,) and the centres' move (k,) px
    (:meth:`Centres.at`). The prior enters
    as residual rows weighed as a maximum a posteriori fit would weigh them against
    the tracks: their scatter (robust RMS) times the square root of ``inflation``, how
    much more the fit moves than independent errors would move it (heat shimmer moves
    whole patches of tracks together). A first fit weighs it by the bend's inflation
    (:func:`_lens_sigmas`) and the residuals with every centre at the rig's; a second,
    from the start again, by the centres' own inflation (:func:`_centre_inflation`)
    and the residuals, both of the first fit: centres assumed wrong leave residuals of
    their own, and weighed by those the prior held the centres short (on exact
    projections the depth scale stayed 0.03-0.13 % off after the first fit, <= 0.007 %
    after the second; issue 35). Without shimmer the views settle the centres to a few
    px; in shimmer the prior holds them near the rig's."""
    weight = _prior_weight(problem, x, prior_px, inflation)
    first, q = _fit_centres_once(problem, x, opts, centres, prior_px, weight, fixed_terms)
    inflation = _centre_inflation(problem, first, centres, blocks)
    if np.isfinite(inflation):  # else too few tracks explained to say: keep the first
        weight = _prior_weight(problem, first, prior_px, inflation)
        problem.centres = centres.given.copy()  # from the start again: from the first's
        # optimum its steps stalled at once on a field frame (a rough Jacobian there)
        return _fit_centres_once(problem, x, opts, centres, prior_px, weight, fixed_terms)
    return first, q


def _prior_weight(problem: Problem, x: np.ndarray, prior_px: float, inflation: float) -> float:
    """The prior rows' weight in :func:`_fit_centres` at the fit ``x``."""
    scatter = 1.4826 * float(np.median(np.abs(problem.residuals(x))))
    return scatter * np.sqrt(max(inflation, 1.0)) / prior_px


def _centre_inflation(problem: Problem, x: np.ndarray, centres: Centres, blocks: int) -> float:
    """How much more the views' centres (those ``problem`` holds, moving as ``centres``
    lets them) move at the fit ``x`` than independent errors would move them: the
    largest ratio, over their k moves, of the cluster-robust variance (``blocks`` x
    ``blocks`` blocks) to the independent one, at least 1; inf where the fit explains
    too few tracks to say."""
    J, r, inlier = plain_jacobian(problem, x, centres.basis)
    if inlier.sum() < MIN_TRACKS:
        return float("inf")
    k = centres.free
    try:
        iid = np.linalg.inv(J.T @ J) * float(r @ r) / max(r.size - J.shape[1] - inlier.sum(), 1)
        labels = np.repeat(spatial_blocks(problem.pl[inlier], blocks), 4)
        clustered = cluster_covariance(J, r, labels, int(inlier.sum()))
    except np.linalg.LinAlgError:
        return float("inf")
    return max(1.0, float(np.max(np.diag(clustered)[-k:] / np.diag(iid)[-k:])))


def _shared_centre_offset_sigma(
    problem: Problem, x: np.ndarray, centres: Centres, prior_px: float
) -> float:
    """The disparity offset's standard error (px) that one camera's centre carries: the
    right camera's yaw (the offset, :mod:`rigkit.pipeline.ambiguity`) follows a centre
    held wrong by the fit's own regression, times the prior's spread ``prior_px`` per
    axis. The prior, not the fit's posterior: on ideal scenes at the paper's protocol
    the tracks settled the centre 12 px off where their scatter said 2.5 px (the
    tracker's errors are structured; docs/results-log.md, issue 35). 0 for three
    cameras, whose centres' prior the ambiguity stage carries; inf where the fit
    explains too few tracks to say."""
    if centres.free != 2:
        return 0.0
    J, _, inlier = plain_jacobian(problem, x, centres.basis)
    if inlier.sum() < MIN_TRACKS:
        return float("inf")
    outer = J.shape[1] - 2
    Jp, Jc = J[:, :outer], J[:, outer:]
    try:  # (P, 2): how far the fit moves per px of a centre held wrong
        follows = np.linalg.solve(Jp.T @ Jp, Jp.T @ Jc)
    except np.linalg.LinAlgError:
        return float("inf")
    yaw = follows[problem.n_terms + 2]
    return problem.lens.focal_px * float(np.linalg.norm(yaw)) * prior_px


def _fit_centres_once(
    problem: Problem, x: np.ndarray, opts: dict, centres: Centres, prior_px: float,
    weight: float, fixed_terms: int,
) -> tuple[np.ndarray, np.ndarray]:
    """One maximum a posteriori fit of :func:`_fit_centres`, from ``x`` and the centres
    ``problem`` holds, the prior's rows weighed by ``weight`` (1/px): the outer
    parameters and the centres' move (k,) px."""
    held, k = x[:fixed_terms], centres.free

    def residuals(q: np.ndarray) -> np.ndarray:
        problem.centres = centres.at(q[-k:])
        r = problem.residuals(np.concatenate([held, q[:-k]])) / LOSS_SCALE_PX
        # The tracks' rows under the robust (Cauchy) loss, as a square root of it; the
        # prior's rows stay quadratic. Under the loss they had stopped pulling past
        # ~0.3 px / weight (~7 px on field frames), and shimmer ran a centre 73 px off.
        robust = np.sign(r) * np.sqrt(np.log1p(r * r)) * LOSS_SCALE_PX
        return np.concatenate([robust, q[-k:] * weight])

    def jacobian(q: np.ndarray) -> np.ndarray:  # of residuals: the chain rule
        problem.centres = centres.at(q[-k:])
        p = np.concatenate([held, q[:-k]])
        r = problem.solved(p) / LOSS_SCALE_PX
        log = np.log1p(r * r)  # d robust / d r = |r| / ((1 + r^2) sqrt(log1p(r^2)))
        slope = np.where(log > 1e-20, np.abs(r) / np.sqrt(np.maximum(log, 1e-300)), 1.0)
        J = problem.jacobian(p, centres.basis)[:, fixed_terms:] * (slope / (1 + r * r))[:, None]
        return np.concatenate([J, np.c_[np.zeros((k, J.shape[1] - k)), weight * np.eye(k)]])

    lower, upper = (b[fixed_terms:] for b in opts["bounds"])
    fit = least_squares(
        residuals, np.concatenate([x[fixed_terms:], np.zeros(k)]), method="trf", jac=jacobian,
        x_scale=np.concatenate([opts["x_scale"][fixed_terms:], np.full(k, 10.0)]),
        bounds=(np.concatenate([lower, np.full(k, -MAX_CENTRE_SIGMAS * prior_px)]),
                np.concatenate([upper, np.full(k, MAX_CENTRE_SIGMAS * prior_px)])),
    )
    residuals(fit.x)  # leave the centres and the depths at the solution
    return np.concatenate([held, fit.x[:-k]]), fit.x[-k:]


def refine_lens(
    m_lr: Matches, m_lb: Matches, rect: Rectification, lens: Lens, rig: RigGeometry,
    settings: PipelineSettings, start: BackStart | None = None,
) -> LensFit:
    """:func:`fit_distortion` from the given ``lens``, in every radial term it uses (at
    most two: the views constrain no more). Where the views rule the given lens out,
    its shape is no start either, and the lens is fitted from no distortion instead,
    flagged (:meth:`LensFit.warning`). On the bundled example with lensfun's P1000
    profile (whose k1, k2 and k3 each move the corner by ~26 px), refining k1 and k2
    with its k3 kept fitted the tracks exactly as well as the fit from nothing (robust
    cost 43.10 against 43.28) but left +4.3 % of depth bias: the tracks cannot tell
    the shapes apart, the depth can. ``start``: as :func:`fit_distortion`'s."""
    _, k2, _, _, k3 = lens.distortion
    terms = max(settings.distortion_terms, 2 if (k2 or k3) else 1)
    first = _fit_terms(m_lr, m_lb, rect, lens, rig, settings, terms, start)
    if lens.identity or not first.result.significant:
        return first.centred()
    # The views rule the given lens out: its centres are not worth fitting.
    # From no distortion, and from the rectification without the rejected lens: started
    # under the P1000 profile (77 px at the corner) one scene settled in a minimum with
    # 5x the tracks' RMS of the fit from nothing.
    bare_rect = pseudo_rectify(m_lr, lens.focal_px, lens.size)
    bare = fit_distortion(m_lr, m_lb, bare_rect, Lens(lens.focal_px, lens.size), rig, settings,
                          start)
    return replace(bare, distortion=bare.fitted, start=lens.distortion, significant=True,
                   start_corner_px=first.result.start_corner_px, start_rejected=True)


def _lens_sigmas(
    x: np.ndarray, problem: Problem, lens: Lens, principal_point_sigma_px: float, blocks: int
) -> tuple[float, float, float, np.ndarray, float]:
    """Standard errors of the corner shift (px), of its part from the tracks' noise
    alone (px), and of the disparity offset (px) that the radial terms' uncertainty
    carries (the later stages take the lens as exact, and this figure is what that
    hides from the offset's standard error), the terms' covariance (n, n) (noise
    and principal points; the terms in the fit's units), and the noise part's
    inflation: its variance at the corner over the one independent errors would give
    (at least 1; inf where there is no fit).

    The noise covariance of the outer parameters (the depths are already eliminated:
    variable projection) is the larger, at the corner, of the Gauss-Newton one, which
    takes every residual as independent, and a cluster-robust one over ``blocks`` x
    ``blocks`` spatial blocks of the left image: heat shimmer moves whole patches of
    tracks together, which the first cannot see. The principal points' consider term
    is added to it. How the right camera's yaw (the y component of its rotation vector)
    follows the terms is the fit's own sensitivity, their regression in the
    Gauss-Newton covariance: how far the yaw moves when the terms are held wrong. The
    cluster-robust covariance's correlations say how the noise moves the two together,
    not how one follows the other; on town bursts they put the lens's share of the
    offset up to 7x too high (docs/results-log.md). A right principal point that moves the
    yaw directly is the back view's to settle, not the lens's."""
    n = problem.n_terms
    # Each term is the fraction of the corner radius it moves the corner by.
    grad = np.full(n, corner_radius(lens) * lens.focal_px)
    Jp, rp, inlier = plain_jacobian(problem, x)
    if inlier.sum() < MIN_TRACKS:
        # The fit explains too few tracks to say how well: as when too few are seen
        # by all three views, it is not taken and the given lens is kept.
        return float("inf"), float("inf"), 0.0, np.full((n, n), np.inf), float("inf")
    # Both from the plain Jacobian and residuals of the tracks the fit explains: the
    # robust fit's own Jacobian is weighted down where its residuals are large, and
    # paired with those residuals (tracks on cars that moved between the captures) it
    # gave a corner sigma of 7.1 px where the inliers say 0.25.
    dof = max(rp.size - Jp.shape[1] - int(inlier.sum()), 1)
    try:
        iid = np.linalg.inv(Jp.T @ Jp) * float(rp @ rp) / dof
        try:
            labels = np.repeat(spatial_blocks(problem.pl[inlier], blocks), 4)
            clustered = cluster_covariance(Jp, rp, labels, int(inlier.sum()))
        except np.linalg.LinAlgError:  # a block the fit cannot do without
            clustered = iid
        noise = max(iid, clustered, key=lambda c: float(grad @ c[:n, :n] @ grad))
        consider = shift_sensitivity(Jp, 4)  # rows per track: right u, v, back u, v
        terms = noise[:n, :n] + (consider @ consider.T)[:n, :n] * 2 * principal_point_sigma_px**2
        yaw_per_term = np.linalg.solve(iid[:n, :n], iid[:n, n + 2])
    except np.linalg.LinAlgError:
        return (float("inf"), float("inf"), float("inf"), np.full((n, n), np.inf),
                float("inf"))
    corner = float(np.sqrt(max(grad @ terms @ grad, 0.0)))
    corner_noise = float(np.sqrt(max(grad @ noise[:n, :n] @ grad, 0.0)))
    offset = float(np.sqrt(max(yaw_per_term @ terms @ yaw_per_term, 0.0)))
    independent = float(grad @ iid[:n, :n] @ grad)
    inflation = corner_noise**2 / independent if independent > 0 else float("inf")
    return corner, corner_noise, lens.focal_px * offset, terms, inflation
