"""The three-view bundle adjustment the lens stage fits (:mod:`rigkit.pipeline.distortion`):
corners tracked from the left view into the right and back ones, one lens, and each
view's principal point.

By variable projection (Golub and Pereyra): every track has one unknown inverse depth,
solved for inside; the outer parameters are the lens's radial increments, the right
camera's baseline angle and rotation, and the back camera's rotation and sideways and
vertical offset. Each view's centre (its principal point, the centre of its bend) is
held in :attr:`Problem.centres`, fitted by the lens stage under a prior, each on its
own or, for one camera moved between the positions, as one (:class:`Centres`).
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from rigkit.geometry import Distortion, distort, rotvec_to_matrix, undistort
from rigkit.pipeline.lens import Lens
from rigkit.pipeline.rectify import Rectification

MAX_BASELINE_TURN_RAD = 0.2  # how far the fit may turn the rectification's baseline
MAX_DEPTH_STEPS = 8
DEPTH_TOL_PX = 1e-6  # far below what the outer fit resolves (its columns hold the depths)
INLIER_PX = 1.0  # tracks within this of the fit count in the standard errors
CENTRE_STEP_PX = 1e-2  # finite-difference step of a view's centre (the residuals are ~linear)


@dataclass(frozen=True)
class Centres:
    """How a fit may move the views' centres: ``given`` (3, 2) px from the image centre
    (left, right, back), where the prior holds them, and ``basis`` (6, k): a step
    ``q`` (k,) moves them to ``given + (basis @ q).reshape(3, 2)``. Three cameras move
    each on its own (k = 6); one camera moved between the positions has one centre,
    which moves as one (k = 2)."""

    given: np.ndarray
    basis: np.ndarray

    @classmethod
    def of(cls, given_px: object, one_camera: bool) -> Centres:
        """For the views' ``given_px`` ((x, y) * 3, px from the image centre)."""
        basis = np.tile(np.eye(2), (3, 1)) if one_camera else np.eye(6)
        return cls(np.array(given_px, dtype=np.float64).reshape(3, 2), basis)

    @property
    def free(self) -> int:
        """k: how many numbers the fit moves them by."""
        return self.basis.shape[1]

    def at(self, q: np.ndarray) -> np.ndarray:
        """(3, 2) px: the centres moved by ``q`` (k,)."""
        return self.given + (self.basis @ q).reshape(3, 2)


def corner_radius(lens: Lens) -> float:
    """The image corner's distance from the centre, normalised (r / f)."""
    w, h = lens.size
    return float(np.hypot(w - 1, h - 1) / 2 / lens.focal_px)


class Problem:
    """The bundle adjustment by variable projection (Golub and Pereyra): the outer
    parameters are ``n_terms`` radial increments (as the fraction of the corner radius
    they move the corner by), the right camera's baseline angle and rotation vector, and
    the back camera's rotation vector and (x, y) offset (m); each track's inverse depth
    is solved for inside, so the outer problem has a handful of unknowns and the
    yaw/depth trade-off cannot slow it down."""

    def __init__(self, lens, tracks, c_lr, c_lb, n_terms, w0, centres: np.ndarray):
        self.lens, self.n_terms = lens, n_terms
        self.c_lr, self.c_lb = c_lr, c_lb
        self.pl, self.pr, self.pb = tracks
        self.rc = corner_radius(lens)
        self.w = np.full(len(self.pl), w0)
        # each view's centre of distortion (3, 2), px from lens.centre
        self.centres = np.array(centres, dtype=np.float64)
        self._solved: tuple[np.ndarray, ...] | None = None  # the last residuals' p, centres, r

    def distortion(self, p: np.ndarray) -> Distortion:
        k = list(self.lens.distortion)
        for j in range(self.n_terms):
            k[j if j < 2 else 4] += p[j] / self.rc ** (2 * (j + 1))
        return (k[0], k[1], k[2], k[3], k[4])

    def _setup(self, p: np.ndarray):
        """Per-parameter constants: the lens, and per other view the left rays (N, 3)
        rotated into it, its rotated centre and the positions it saw."""
        d = self.distortion(p)
        rays = self._rays(d)
        return d, [self._view(p, i, rays) for i in (0, 1)]

    def _rays(self, d: Distortion) -> np.ndarray:
        """(N, 3): the left view's rays under the lens ``d``, about its centre."""
        nl = (self.pl - self.lens.centre - self.centres[0]) / self.lens.focal_px
        x, y = undistort(nl[:, 0], nl[:, 1], d)
        return np.stack([x, y, np.ones_like(x)], axis=1)

    def _view(self, p: np.ndarray, i: int, rays: np.ndarray):
        """View ``i`` (0 right, 1 back): the left ``rays`` rotated into it, its rotated
        centre, the positions it saw and its principal point (px)."""
        n, f = self.n_terms, self.lens.focal_px
        if i == 0:
            phi = p[n]
            c = self.c_lr * np.array([np.cos(phi), np.sin(phi), 0.0])
            rv, seen = p[n + 1 : n + 4], self.pr
        else:
            c = np.array([p[n + 7], p[n + 8], -self.c_lb])
            rv, seen = p[n + 4 : n + 7], self.pb
        # A view's centre moved by c moves its image as a turn by c / f nearly does; each
        # rotation is taken about the views' centres (the turn that moves the image centre
        # by c: rotation vector (-c_y, c_x, 0) / f), so that a centre's own column holds
        # what no turn does. Without it the fit crawled along that valley and stopped
        # tens of px short, its gradient far from zero.
        centre = self.centres[i + 1]
        R = turn(-centre / f) @ rotvec_to_matrix(rv) @ turn(self.centres[0] / f)
        return rays @ R.T, R @ c, seen, self.lens.centre + centre

    def _view_residuals(self, d: Distortion, view, w: np.ndarray) -> np.ndarray:
        """(N, 2): one view's reprojection errors (px) for inverse depths ``w``."""
        rays, Rc, seen, centre = view
        Xc = rays - w[:, None] * Rc
        x, y = distort(Xc[:, 0] / Xc[:, 2], Xc[:, 1] / Xc[:, 2], d)
        return np.stack([x, y], axis=1) * self.lens.focal_px + centre - seen

    def _view_and_depth_column(self, d: Distortion, view, w: np.ndarray):
        """One view's reprojection errors (N, 2) px, as :meth:`_view_residuals`, and
        their derivative in the inverse depths (N, 2) px m (exact: the projection's
        and the lens's derivatives)."""
        rays, Rc, seen, centre = view
        Xc = rays - w[:, None] * Rc
        z = Xc[:, 2]
        x, y = Xc[:, 0] / z, Xc[:, 1] / z
        dx, dy = (x * Rc[2] - Rc[0]) / z, (y * Rc[2] - Rc[1]) / z
        (xd, yd), (dxd, dyd) = distort(x, y, d), _distort_along(x, y, dx, dy, d)
        f = self.lens.focal_px
        return (np.stack([xd, yd], axis=1) * f + centre - seen,
                np.stack([dxd, dyd], axis=1) * f)

    def _track_residuals(self, setup, w: np.ndarray) -> np.ndarray:
        """(N, 4): right (u, v) and back (u, v) reprojection errors, px, for inverse
        depths ``w`` (1/m). The point ray / w seen from centre c projects as
        R ray - w R c (up to scale)."""
        d, views = setup
        return np.concatenate([self._view_residuals(d, v, w) for v in views], axis=1)

    def residuals(self, p: np.ndarray) -> np.ndarray:
        setup = self._setup(p)
        w = self.w  # warm start: the last call's depths are within a step of these
        r = self._track_residuals(setup, w)
        for _ in range(MAX_DEPTH_STEPS):  # Gauss-Newton per track, nearly linear in w
            h = 1e-3 * w  # nearly linear: a wide step is exact and far above rounding
            J = (self._track_residuals(setup, w + h) - r) / h[:, None]
            step = -(J * r).sum(axis=1) / np.maximum((J * J).sum(axis=1), 1e-300)
            w = w + step
            r = self._track_residuals(setup, w)
            # Converged when the residuals (but those of a few hopeless tracks, which
            # the robust loss ignores) move by less than DEPTH_TOL_PX.
            moved = np.abs(step) * np.sqrt((J * J).sum(axis=1))
            if np.percentile(moved, 99) < DEPTH_TOL_PX:
                break
        self.w = w
        self._solved = (np.array(p, dtype=np.float64), self.centres.copy(), r.ravel())
        return r.ravel()

    def solved(self, p: np.ndarray) -> np.ndarray:
        """:meth:`residuals` at ``p``, without solving for the depths again where the
        last call was at ``p`` (and the same centres)."""
        last = self._solved
        if (last is not None and np.array_equal(last[0], p)
                and np.array_equal(last[1], self.centres)):
            return last[2].copy()
        return self.residuals(p)

    def jacobian(self, p: np.ndarray, moves: np.ndarray | None = None) -> np.ndarray:
        """(4 N, P [+ k]): the Jacobian of :meth:`residuals` (the depths solved for
        inside) at ``p``; with ``moves``, a (6, k) basis of the views' centres' moves
        (:attr:`Centres.basis`), k more columns at the end, per unit of each.

        Variable projection's reduced Jacobian (Golub and Pereyra, SIAM J. Numer. Anal.
        10, 1973; Kaufman, BIT 15, 1975), per track, whose one depth w the residuals r
        hold at a minimum (J_w . r = 0): a parameter's column is its column with the
        depths held, J_k, plus the depth's column J_w times how far the depth follows,
        -(J_w . J_k + r . dJ_w/dp_k) / (J_w . J_w + r . dJ_w/dw). Kaufman's
        simplification leaves out the terms in r, which the gradient does not see but
        the columns do (up to 0.3 % at 0.3 px of noise); kept here, the columns are
        the reduced residuals' own. J_k by forward differences of the views the
        parameter moves, with the depths held (no depth solve), J_w exactly: one
        view's residuals per column instead of a depth solve's several, and free of
        its tolerance (~1e-6 px, the finite differences' noise at ~1e-3 of a column)."""
        self.solved(p)  # the depths that belong to p
        d, w, n = self.distortion(p), self.w, self.n_terms
        rays = self._rays(d)
        views = [self._view(p, i, rays) for i in (0, 1)]
        r0, jw0 = zip(*(self._view_and_depth_column(d, v, w) for v in views), strict=True)
        r, Jw = np.concatenate(r0, axis=1), np.concatenate(jw0, axis=1)
        h = 1e-4 * w  # the depth column is nearly constant in w: central, far above rounding
        Jww = np.concatenate([self._view_and_depth_column(d, v, w + h)[1]
                              - self._view_and_depth_column(d, v, w - h)[1]
                              for v in views], axis=1) / (2 * h[:, None])
        curvature = (Jw * Jw).sum(axis=1) + (r * Jww).sum(axis=1)
        moves = np.zeros((6, 0)) if moves is None else moves
        J = np.zeros((len(w), 4, p.size + moves.shape[1]))
        follow = np.zeros((len(w), J.shape[2]))  # J_w . J_k + r . dJ_w/dp_k
        held = self.centres
        for k in range(J.shape[2]):
            if k < p.size:
                step, q = 1e-6 * max(1.0, abs(p[k])), p.copy()
                q[k] += step
                lens = k < n
                touched: tuple[int, ...] = (0, 1) if lens else ((0,) if k < n + 4 else (1,))
            else:
                step, q, move = CENTRE_STEP_PX, p, moves[:, k - p.size].reshape(3, 2)
                self.centres = held + step * move
                lens = bool(np.any(move[0]))
                touched = tuple(i for i in (0, 1) if lens or np.any(move[i + 1]))
            dq = self.distortion(q)
            moved = self._rays(dq) if lens else rays
            for i in touched:
                rk, jwk = self._view_and_depth_column(dq, self._view(q, i, moved), w)
                cols = slice(2 * i, 2 * i + 2)
                J[:, cols, k] = (rk - r0[i]) / step
                follow[:, k] += ((Jw[:, cols] * J[:, cols, k]).sum(axis=1)
                                 + (r[:, cols] * (jwk - jw0[i])).sum(axis=1) / step)
            self.centres = held
        J -= Jw[:, :, None] * (follow / np.maximum(curvature, 1e-300)[:, None])[:, None, :]
        return J.reshape(4 * len(w), -1)


def _distort_along(x, y, dx, dy, d: Distortion) -> tuple[np.ndarray, np.ndarray]:
    """The derivative of :func:`~rigkit.geometry.distort` at ``(x, y)`` along
    ``(dx, dy)`` (normalised units)."""
    k1, k2, p1, p2, k3 = d
    r2 = x * x + y * y
    radial = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3))
    dr2 = 2.0 * (x * dx + y * dy)
    grow = (k1 + r2 * (2.0 * k2 + 3.0 * k3 * r2)) * dr2
    cross = dx * y + x * dy
    return (dx * radial + x * grow + 2.0 * p1 * cross + p2 * (dr2 + 4.0 * x * dx),
            dy * radial + y * grow + p1 * (dr2 + 4.0 * y * dy) + 2.0 * p2 * cross)


def turn(shift: np.ndarray) -> np.ndarray:
    """The rotation that moves the image centre by ``shift`` (2,) (normalised units)."""
    return rotvec_to_matrix(np.array([-shift[1], shift[0], 0.0]))


def initial(
    problem: Problem, rect: Rectification, back_rotvec: np.ndarray
) -> np.ndarray:
    """Start: the rectification's right rotation and baseline angle, the back view's
    rotation from its coarse affine map (:func:`~rigkit.pipeline.ambiguity.back_view_start`)."""
    baseline = rect.R_rect.T @ np.array([1.0, 0.0, 0.0])
    rv, _ = cv2.Rodrigues(rect.R_lr.T)
    return np.concatenate(
        [
            np.zeros(problem.n_terms),
            [np.arctan2(baseline[1], baseline[0])],
            rv.ravel(),
            back_rotvec,
            [0.0, 0.0],
        ]
    )


def bounds(p0: np.ndarray, n_terms: int, baseline_lb_m: float) -> tuple[np.ndarray, ...]:
    """Bounds on the parameters (lower, upper): the right camera's baseline direction
    within ``MAX_BASELINE_TURN_RAD`` of the rectification's (which the left/right rows
    settle), the back camera's sideways and vertical offset under its distance
    behind; the rest free. Without them, on one field scene the first (plain) pass let
    bad tracks turn the baseline by 92 deg and lift the back camera 4 m, a minimum the
    robust pass did not leave (the corner's sigma 18 px, the offset's 73 % of depth;
    docs/results-log.md)."""
    lower, upper = np.full(p0.size, -np.inf), np.full(p0.size, np.inf)
    phi = n_terms
    lower[phi], upper[phi] = p0[phi] - MAX_BASELINE_TURN_RAD, p0[phi] + MAX_BASELINE_TURN_RAD
    lower[-2:], upper[-2:] = -baseline_lb_m, baseline_lb_m
    return lower, upper


def plain_jacobian(
    problem: Problem, p: np.ndarray, centres: np.ndarray | None = None
) -> tuple[np.ndarray, ...]:
    """The residuals' plain (not loss-weighted) Jacobian and the residuals themselves,
    on the tracks within ``INLIER_PX`` of the fit, as the fit's own
    (:meth:`Problem.jacobian`): (4 M, P), (4 M,) and the (N,) bool mask of those M tracks; with
    ``centres``, a (6, k) basis of the views' centres' moves (:attr:`Centres.basis`),
    k more columns at the end for them."""
    r0 = problem.solved(p)
    inlier = np.abs(r0).reshape(-1, 4).max(axis=1) < INLIER_PX
    J = problem.jacobian(p, centres)
    rows = np.repeat(inlier, 4)
    return J[rows], r0[rows], inlier
