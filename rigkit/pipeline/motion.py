"""How another view moved against the left one, from its matches alone, at any depth.

The checks that refuse a capture before it gives a wrong depth (the back view is not
magnified, right and back are swapped, the zoom changed) and the starting points of
the fits that follow (:mod:`rigkit.pipeline.distortion`, :mod:`rigkit.pipeline.ambiguity`)
need each view's *size* against the left one: a back view C_lb behind shows the scene
``z / (z + C_lb)`` as large, a right view beside the left one as large. An affine map
fitted to the matches measures that size only where the scene is at one depth: where
the depth varies across the view (ground receding from 200 to 450 m), the parallax of
the right view's baseline shears its map, and the back camera's small sideways or
vertical offset stretches its map along that offset by up to a few percent, more than
the magnification itself (0.7 % at 300 m).

So each match's own depth is a free unknown here. To first order in the turn and in
C / z, a left point at normalised position ``p = (x, y)`` with inverse depth ``w``
appears in a view turned by the rotation vector ``r`` and moved to ``T`` (left frame,
m) at::

    x' = x + r_y (1 + x^2) - r_x x y - r_z y + s x + w (-T_x + T_z x)
    y' = y - r_x (1 + y^2) + r_y x y + r_z x + s y + w (-T_y + T_z y)

with ``s`` the view's scale against the left one. Each match ``i`` gets its own
``w_i`` (relative: their mean is 0, each weighed by its precision, so that ``s`` is the
scale at the matches' mean inverse depth, ~uniformly weighed where the right view holds
the depths, by ``|p - (T_x, T_y) / T_z|^2`` for a back view alone); ``T`` is known
along the axis the view moved (the right view: x; the back view: z, behind) and free
across it (the tripod's offsets, held by a weak prior). The model is linear in
``(r, s)`` and in each ``w_i``, bilinear in ``w`` and ``T``: Gauss-Newton steps solve
for all at once, each ``w_i`` eliminated in closed form (Schur's complement), with
Cauchy weights that discount matches no depth explains. Along the parallax of each
match its own ``w_i`` absorbs what depth does, so the scale is read off across it: for
the right view from the rows' spacing, for the back view from its contraction across
the direction towards its epipole. The turn is then taken out exactly and the model
fitted again, and the scale's standard error comes from a spatial block jackknife.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import cv2
import numpy as np

from rigkit.core.threads import deterministic
from rigkit.errors import PipelineError
from rigkit.geometry import rotvec_to_matrix
from rigkit.pipeline.checks import check_magnification
from rigkit.pipeline.features import Matches

ITERATIONS = 20
"""Gauss-Newton steps at most; the fit stops earlier once no scale moves by more than
:data:`SCALE_TOL`."""
SCALE_TOL = 1e-8
BLOCKS = 3
"""Blocks per side of the jackknife's grid (:func:`_jackknife`)."""
OFFSET_PRIOR = 0.25
"""One standard deviation of a view's offset across its axis, in units of its baseline
along it: 0.5 m for a back camera 2 m behind, more than a tripod set up again leaves."""
TURNS = 3
"""Times the turn found is taken out exactly and the model fitted again: a roll of 5
deg scales the view by cos(5 deg) = 0.996 at second order, half the magnification."""
MIN_MATCHES = 12
CAUCHY_SCALE = 2.5
"""Residuals beyond this many robust standard deviations count for less and less."""
FLOOR_PX = 0.02
"""The least robust scale of the residuals (px): rendered views can leave less."""


@dataclass(frozen=True)
class ViewMotion:
    """What :func:`view_motion` found for one view against the left one.

    ``scale``: the view's size against the left one at the matches' mean inverse depth,
    with the parallax of their depths taken out (a right view ~1, a back view C_lb
    behind ``z / (z + C_lb)``, a zoomed view its zoom); ``rotvec`` (3,) rad, the turn
    left -> view (the rotation matrix's vector, about the principal point assumed) that
    moves the image as the view's pose does at the matches' mean depth: the parallax
    of its offset across the axis there is a shift the turn takes (what the fits that
    start from it with no offset need);
    ``translation`` (3,): where the view moved, left frame, in units of the baseline
    along its axis (``(1, ., 0)`` for the right view, ``(., ., -1)`` for the back one);
    ``rms_px``: the matches' RMS residual, px (Cauchy-weighted); ``matches``: how many
    carried weight (Cauchy weight over 0.5); ``scale_sigma``: the scale's standard
    error, by a spatial block jackknife (:func:`_jackknife`: heat shimmer's errors are
    shared by neighbouring matches).
    """

    scale: float
    rotvec: np.ndarray
    translation: np.ndarray
    rms_px: float
    matches: int
    scale_sigma: float = 0.0


@dataclass(frozen=True)
class View:
    """One view's side of a fit: its points ``q`` (N, 2), normalised, and the axis it
    moved along, ``"x"`` (the right view) or ``"z"`` (the back view, behind)."""

    q: np.ndarray
    axis: str


@deterministic
def view_motion(m: Matches, focal_px: float, centre: np.ndarray, axis: str) -> ViewMotion:
    """Fit the first-order motion model (module docstring) to ``m`` (left -> view, px)
    for a view that moved along ``axis`` (:class:`View`). ``centre`` (2,): the
    principal point assumed (px). Each match's depth is free, so where the depth
    varies mostly along the view's own parallax, the direction of a back view's
    sideways and vertical offset is weakly held (its scale less so):
    :func:`rig_motion` fits both views with one depth per track."""
    _enough(len(m.left))
    p = (m.left - centre) / focal_px
    return fit_views(p, [View((m.other - centre) / focal_px, axis)], focal_px)[0]


@deterministic
def rig_motion(m_lr: Matches, m_lb: Matches, focal_px: float, centre: np.ndarray,
               tracks: tuple[np.ndarray, np.ndarray, np.ndarray]
               ) -> tuple[ViewMotion, ViewMotion]:
    """The right and the back view's motion, fitted together on the ``tracks`` (left,
    right, back px, (N, 2) each: corners seen in all three) with one inverse depth per
    track: the right view's parallax holds each depth, the back view's offset and scale
    follow. With too few tracks, each view is fitted on its own matches."""
    pl, pr, pb = tracks
    if len(pl) < MIN_MATCHES:
        return (view_motion(m_lr, focal_px, centre, "x"),
                view_motion(m_lb, focal_px, centre, "z"))
    right, back = fit_views((pl - centre) / focal_px,
                            [View((pr - centre) / focal_px, "x"),
                             View((pb - centre) / focal_px, "z")], focal_px)
    return right, back


BackStart = tuple[float, np.ndarray]
"""Where the fits of the back view start: the range (m) its magnification implies and
its rotation vector (3,), rad, left -> back (:func:`back_view_start`)."""


def back_view_start(back: ViewMotion, baseline_lb_m: float) -> BackStart:
    """From the back view's motion: the range (m) its magnification implies at the
    matches' mean inverse depth (PipelineError where it shows none, or none clear of
    three standard errors, :func:`~rigkit.pipeline.checks.check_magnification`) and its
    rotation vector (3,) (rad, left -> back): where the fits of the lens and of the
    offset start."""
    return (check_magnification(back.scale, baseline_lb_m, back.scale_sigma),
            back.rotvec.copy())


def _enough(n: int) -> None:
    if n < MIN_MATCHES:
        raise PipelineError(f"only {n} matches to measure the view's motion "
                            f"(need {MIN_MATCHES})")


def fit_views(p: np.ndarray, views: list[View], focal_px: float) -> list[ViewMotion]:
    """Fit the model to left points ``p`` (N, 2, normalised) seen in ``views`` with one
    inverse depth per point, each view's turn taken out exactly and the model fitted
    again (:data:`TURNS`); its RMS in px of ``focal_px``."""
    turns = [np.eye(3) for _ in views]
    fits: list[ViewMotion] | None = None
    for k in range(TURNS):
        seen = [replace(v, q=_turned_back(v.q, R)) for v, R in zip(views, turns, strict=True)]
        fits = _fit(p, seen, FLOOR_PX / focal_px, fits, last=k == TURNS - 1)
        turns = [R @ rotvec_to_matrix(f.rotvec) for R, f in zip(turns, fits, strict=True)]
    assert fits is not None
    return [replace(f, rotvec=_rotvec(R), rms_px=f.rms_px * focal_px)
            for f, R in zip(fits, turns, strict=True)]


def _turned_back(q: np.ndarray, R: np.ndarray) -> np.ndarray:
    """Normalised points ``q`` (N, 2) seen through the turn ``R`` undone: R^T applied
    to their rays, projected."""
    rays = np.column_stack([q, np.ones(len(q))]) @ R  # rows: (R^T ray)^T
    return rays[:, :2] / rays[:, 2:3]


def _rotvec(R: np.ndarray) -> np.ndarray:
    """The rotation vector (3,) of ``R``."""
    return cv2.Rodrigues(R)[0].ravel()


NOMINAL = {"x": np.array([1.0, 0.0, 0.0]), "z": np.array([0.0, 0.0, -1.0])}
FREE = {"x": [1], "z": [0, 1]}
"""A view's translation along its axis is the unit; across it, it is fitted."""


def _fit(p: np.ndarray, views: list[View], floor: float,
         start: list[ViewMotion] | None, last: bool = True) -> list[ViewMotion]:
    """One fit of the first-order model (module docstring) of normalised left points
    ``p`` seen in ``views`` (their turns so far taken out), from ``start``'s
    translations (None: straight along each view's axis), by Gauss-Newton steps on the
    product of depth and translation, reweighted (Cauchy) at each; the scales' standard
    errors where it is the ``last`` (else 0)."""
    x, y = p[:, 0], p[:, 1]
    # Each view's columns of (r_x, r_y, r_z, s) per point: (N, 2, 4)
    a = np.zeros((len(p), 2, 4))
    a[:, 0] = np.stack([-x * y, 1 + x * x, -y, x], axis=1)
    a[:, 1] = np.stack([-(1 + y * y), x * y, x, y], axis=1)
    deltas = [v.q - p for v in views]  # (N, 2) each
    T = ([NOMINAL[v.axis].copy() for v in views] if start is None else
         [s.translation.copy() for s in start])
    free = [FREE[v.axis] for v in views]
    w, weight = np.zeros(len(p)), np.ones(len(p))
    thetas = [np.zeros(4) for _ in views]
    residual = np.zeros(len(p))
    noise = floor
    for _ in range(ITERATIONS):
        noise = max(float(np.sqrt(np.average(residual**2, weights=weight))), floor)
        new, w, moves = _step(a, deltas, p, T, free, w, weight, noise)
        for t, f, m in zip(T, free, moves, strict=True):
            t[f] += m
        errs = [d - a @ th - w[:, None] * _depth_columns(p, t)
                for d, th, t in zip(deltas, new, T, strict=True)]
        residual = np.sqrt(sum(np.sum(e**2, axis=1) for e in errs) / len(views))
        weight = _cauchy(residual, floor)
        converged = max(abs(n[3] - o[3]) for n, o in zip(new, thetas, strict=True)) < SCALE_TOL
        thetas = new
        if converged:
            break
    rms = float(np.sqrt(np.average(residual**2, weights=weight)))
    sigmas = (_jackknife(a, deltas, p, T, free, w, weight, noise) if last
              else [0.0] * len(views))
    return [ViewMotion(scale=float(1.0 + th[3]), rotvec=th[:3].copy(), translation=t,
                       rms_px=rms, matches=int((weight > 0.5).sum()), scale_sigma=sigma)
            for th, t, sigma in zip(thetas, T, sigmas, strict=True)]


def _jackknife(a: np.ndarray, deltas: list[np.ndarray], p: np.ndarray, T: list[np.ndarray],
               free: list[list[int]], w: np.ndarray, weight: np.ndarray, noise: float
               ) -> list[float]:
    """Each view's scale's standard error by the delete-one-block jackknife over a
    :data:`BLOCKS` x :data:`BLOCKS` grid of the left points (a Gauss-Newton step from
    the fit without each block): heat shimmer moves whole patches of matches, and a
    flat scene's offsets follow its depths' noise; neither is independent error, which
    the least squares' own covariance assumes."""
    labels = spatial_blocks(p, BLOCKS)
    scales = []
    for b in np.unique(labels):
        thetas, _, _ = _step(a, deltas, p, T, free, w, np.where(labels == b, 0.0, weight),
                             noise)
        scales.append([th[3] for th in thetas])
    n = len(scales)
    if n < 2:
        return [0.0] * len(deltas)
    spread = np.asarray(scales)
    return list(np.sqrt((n - 1) / n * np.sum((spread - spread.mean(axis=0)) ** 2, axis=0)))


def spatial_blocks(px: np.ndarray, blocks: int) -> np.ndarray:
    """Which of a ``blocks`` x ``blocks`` grid over the points' bounding box each of
    the (N, 2) pixel positions ``px`` lies in: (N,) int labels. Blocks far wider than
    heat shimmer's patches hold errors that are nearly independent of each other's."""
    lo, hi = px.min(axis=0), px.max(axis=0) + 1e-9
    cell = np.floor((px - lo) / (hi - lo) * blocks).astype(int)
    return cell[:, 1] * blocks + cell[:, 0]



def _step(a: np.ndarray, deltas: list[np.ndarray], p: np.ndarray, T: list[np.ndarray],
          free: list[list[int]], w0: np.ndarray, weight: np.ndarray, noise: float
          ) -> tuple[list[np.ndarray], np.ndarray, list[np.ndarray]]:
    """One weighted Gauss-Newton step: every view's (r_x, r_y, r_z, s), every point's
    inverse depth w and the move of each view's free translation components, the
    product w T linearised about the last depths ``w0``. Each point's w is eliminated
    (its rows projected off its depth column c: Schur's complement) and the w's mean,
    each weighed by its precision (|c|^2 and the Cauchy weight), held at 0 by a
    Lagrange multiplier (the scales are the mean depth's: a common shift of every w is
    a turn and a scale, all but its second-order part). The free
    translation components are held towards 0 (no offset across the axis) by a prior of
    :data:`OFFSET_PRIOR` baselines, weighed against the residuals' ``noise``
    (normalised units).
    ``a``: (N, 2, 4) one view's turn and scale columns per point; ``deltas``: (N, 2)
    per view."""
    n, views = len(p), len(deltas)
    k = 4 * views + sum(len(f) for f in free)
    A = np.zeros((n, 2 * views, k))
    col = 4 * views
    for v in range(views):
        A[:, 2 * v:2 * v + 2, 4 * v:4 * v + 4] = a
        for axis in free[v]:  # moving T along axis moves each point by -w0 there
            A[:, 2 * v + axis, col] = -w0
            col += 1
    c = np.concatenate([_depth_columns(p, t) for t in T], axis=1)  # (N, 2V)
    d = np.concatenate(deltas, axis=1)
    cc = np.maximum((c * c).sum(axis=1), 1e-300)
    cA = np.matmul(c[:, None, :], A)[:, 0]  # c^T A per point
    cd = (c * d).sum(axis=1)
    PA = A - c[:, :, None] * (cA / cc[:, None])[:, None, :]
    Pd = d - c * (cd / cc)[:, None]
    rows = PA.reshape(-1, k)  # one row per point and view component
    weighted = rows * np.repeat(weight, 2 * views)[:, None]
    H = weighted.T @ rows
    g = weighted.T @ Pd.ravel()
    prior = (noise / OFFSET_PRIOR) ** 2
    offsets = np.concatenate([t[f] for t, f in zip(T, free, strict=True)])
    H[4 * views:, 4 * views:] += prior * np.eye(k - 4 * views)
    g[4 * views:] -= prior * offsets
    # sum_i weight_i |c_i|^2 w_i = 0: the mean of the w's, each weighed by its precision
    x = np.linalg.solve(_kkt(H, weight @ cA), np.append(g, float(weight @ cd)))[:k]
    w = (cd - cA @ x) / cc
    moves, col = [], 4 * views
    for f in free:
        moves.append(x[col:col + len(f)])
        col += len(f)
    return [x[4 * v:4 * v + 4] for v in range(views)], w, moves


def _kkt(H: np.ndarray, row: np.ndarray) -> np.ndarray:
    """The normal equations ``H`` bordered by one linear constraint ``row``."""
    k = len(row)
    kkt = np.zeros((k + 1, k + 1))
    kkt[:k, :k], kkt[:k, k], kkt[k, :k] = H, row, row
    return kkt


def _depth_columns(p: np.ndarray, T: np.ndarray) -> np.ndarray:
    """(N, 2): the normalised displacement of each point per unit of inverse depth for
    a camera moved to ``T``: ``-T_xy + T_z p``."""
    return -T[:2] + T[2] * p


def _cauchy(residual: np.ndarray, floor: float) -> np.ndarray:
    """Cauchy weights of residuals (normalised units), scaled by their robust spread
    (at least ``floor``)."""
    scale = CAUCHY_SCALE * max(1.4826 * float(np.median(residual)), floor)
    return 1.0 / (1.0 + (residual / scale) ** 2)
