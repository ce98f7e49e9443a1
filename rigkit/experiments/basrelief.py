"""The bas-relief simulation of the paper's sec. 5.1: two-view SfM on a distant surface.

A Gaussian hill ``z = a + b exp(-(x^2 + y^2) / (2 s^2))`` (a = b = 300 m, s = 10 m) is
seen by a left camera at the origin and a right camera at (2, 0, 0) m, both with the
identity orientation, 4608x3456 px, 6 deg horizontal FOV, centred principal points.
1,500 surface points seen by both cameras are projected; the right pixels get Gaussian
noise. From these matches and the true intrinsics, the essential matrix (RANSAC,
OpenCV's five-point solver) and its decomposition give the relative pose, refined by
minimising the Sampson error of all inliers (two-view bundle adjustment to first
order); the translation is scaled to the true 2 m and the points are triangulated.
The rotation about y, which trades off against depth (the bas-relief ambiguity), is
where the error goes.

Noise: the paper writes N(0, diag(1/sqrt 2, 1/sqrt 2)), a covariance, so the default
standard deviation per axis is 2^-1/4 = 0.84 px; ``noise_sigma_px`` sets another.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np
from scipy.optimize import least_squares

from rigkit.geometry import focal_from_fov, intrinsics, rotvec_to_matrix

NOISE_SIGMA_PX = 2.0**-0.25
GOOD_BASELINE_DEG = 5.0  # baseline direction error of the runs the figure draws from


@dataclass(frozen=True)
class BasReliefSetup:
    """Sec. 5.1's scene and cameras (metres, px, degrees)."""

    a: float = 300.0
    b: float = 300.0
    sigma: float = 10.0
    baseline_m: float = 2.0
    width: int = 4608
    height: int = 3456
    hfov_deg: float = 6.0
    n_points: int = 1500
    noise_sigma_px: float = NOISE_SIGMA_PX

    @property
    def K(self) -> np.ndarray:
        f = focal_from_fov(self.width, self.hfov_deg)
        return intrinsics(f, (self.width - 1) / 2, (self.height - 1) / 2)


@dataclass(frozen=True)
class BasReliefRun:
    """One run: ``euler_error_deg`` (3,) x, y, z Euler angles (R = Rz Ry Rx) of the
    recovered right-camera orientation (the truth is the identity); ``t_error_deg``:
    angle between recovered and true baseline directions; ``points_true`` and
    ``points_est`` (N, 3) metres in the left frame; ``depth_error`` (N,) relative
    (estimate - truth) / truth of z."""

    euler_error_deg: np.ndarray
    t_error_deg: float
    points_true: np.ndarray
    points_est: np.ndarray
    depth_error: np.ndarray


def surface_points(setup: BasReliefSetup, rng: np.random.Generator) -> np.ndarray:
    """``n_points`` (N, 3) points of the Gaussian surface seen by both cameras."""
    K, C = setup.K, np.array([setup.baseline_m, 0.0, 0.0])
    half_w = setup.a * setup.width / 2 / K[0, 0]
    half_h = setup.a * setup.height / 2 / K[0, 0]
    out = np.empty((0, 3))
    while len(out) < setup.n_points:
        x = rng.uniform(-half_w, half_w + setup.baseline_m, 4 * setup.n_points)
        y = rng.uniform(-half_h, half_h, x.size)
        z = setup.a + setup.b * np.exp(-(x * x + y * y) / (2 * setup.sigma**2))
        X = np.column_stack([x, y, z])
        seen = _inside(project(K, np.eye(3), np.zeros(3), X), setup)
        seen &= _inside(project(K, np.eye(3), C, X), setup)
        out = np.vstack([out, X[seen]])
    return out[: setup.n_points]


def project(K: np.ndarray, R: np.ndarray, C: np.ndarray, X: np.ndarray) -> np.ndarray:
    """Pixels (N, 2) of points ``X`` (N, 3) in a camera with world->camera ``R``, centre ``C``."""
    Xc = (X - C) @ R.T
    return Xc[:, :2] / Xc[:, 2:3] * K[0, 0] + K[:2, 2]


def _inside(uv: np.ndarray, setup: BasReliefSetup) -> np.ndarray:
    return (
        (uv[:, 0] >= 0) & (uv[:, 0] <= setup.width - 1)
        & (uv[:, 1] >= 0) & (uv[:, 1] <= setup.height - 1)
    )


def _sampson_residuals(p: np.ndarray, xl: np.ndarray, xr: np.ndarray, f: float) -> np.ndarray:
    """Sampson errors (px at focal length ``f``) of normalised homogeneous points
    ``xl``, ``xr`` (N, 3) for rotation vector p[:3] and baseline direction p[3:5]."""
    R = rotvec_to_matrix(p[:3])
    E = np.cross(np.eye(3), _direction(p[3:])) @ R  # [t]_x R
    Ex, Etx = xl @ E.T, xr @ E
    num = np.einsum("ij,ij->i", xr, Ex)
    den = np.sqrt(Ex[:, 0] ** 2 + Ex[:, 1] ** 2 + Etx[:, 0] ** 2 + Etx[:, 1] ** 2)
    return f * num / den


def _triangulate(K: np.ndarray, R: np.ndarray, t: np.ndarray, pl, pr) -> np.ndarray:
    """Linear triangulation: left-frame points (N, 3) for ``x_r ~ R x_l + t``."""
    P1 = K @ np.hstack([np.eye(3), np.zeros((3, 1))])
    P2 = K @ np.hstack([R, t.reshape(3, 1)])
    Xh = cv2.triangulatePoints(P1, P2, pl.T.astype(np.float64), pr.T.astype(np.float64))
    return (Xh[:3] / Xh[3]).T


def _in_front(K: np.ndarray, R: np.ndarray, t: np.ndarray, pl, pr) -> int:
    """How many matches triangulate in front of both cameras (the cheirality test)."""
    X = _triangulate(K, R, t, pl, pr)
    return int(np.count_nonzero((X[:, 2] > 0) & ((X @ R.T + t)[:, 2] > 0)))


def _direction(p: np.ndarray) -> np.ndarray:
    """Unit vector from (azimuth in the x-z plane, elevation), rad."""
    return np.array([np.cos(p[1]) * np.cos(p[0]), np.sin(p[1]), np.cos(p[1]) * np.sin(p[0])])


def relative_pose(
    pl: np.ndarray, pr: np.ndarray, K: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Two-view SfM: (R (3, 3), t (3,) unit) with ``x_r ~ R x_l + t`` (camera frames),
    from matches ``pl`` <-> ``pr`` ((N, 2) px) and intrinsics ``K`` (3, 3).

    Essential matrix by RANSAC (1 px), the decomposition that puts the points in
    front of both cameras, then (R, t) refined on the inliers by Sampson error."""
    E, mask = cv2.findEssentialMat(pl, pr, K, method=cv2.RANSAC, prob=0.999, threshold=1.0)
    inl = mask.ravel() > 0
    pl, pr = pl[inl], pr[inl]
    R1, R2, t0 = cv2.decomposeEssentialMat(E[:3])
    candidates = [(R, s * t0.ravel()) for R in (R1, R2) for s in (1, -1)]
    R, t = max(candidates, key=lambda c: _in_front(K, c[0], c[1], pl, pr))
    Ki = np.linalg.inv(K)
    xl = np.column_stack([pl, np.ones(len(pl))]) @ Ki.T
    xr = np.column_stack([pr, np.ones(len(pr))]) @ Ki.T
    p0 = np.r_[cv2.Rodrigues(R)[0].ravel(), np.arctan2(t[2], t[0]), np.arcsin(t[1])]
    p = least_squares(_sampson_residuals, p0, args=(xl, xr, K[0, 0]), x_scale=1e-4).x
    R, t = rotvec_to_matrix(p[:3]), _direction(p[3:])
    # The Sampson error does not see the sign of t: cheirality decides it again.
    return (R, t) if _in_front(K, R, t, pl, pr) >= _in_front(K, R, -t, pl, pr) else (R, -t)


def euler_xyz_deg(R: np.ndarray) -> np.ndarray:
    """(x, y, z) Euler angles in degrees of ``R = Rz(z) Ry(y) Rx(x)``."""
    y = np.arcsin(-np.clip(R[2, 0], -1, 1))
    x = np.arctan2(R[2, 1], R[2, 2])
    z = np.arctan2(R[1, 0], R[0, 0])
    return np.degrees([x, y, z])


def run_once(setup: BasReliefSetup, rng: np.random.Generator) -> BasReliefRun:
    """One simulation: sample, project, add noise, recover the pose, triangulate."""
    K, C = setup.K, np.array([setup.baseline_m, 0.0, 0.0])
    X = surface_points(setup, rng)
    pl = project(K, np.eye(3), np.zeros(3), X)
    pr = project(K, np.eye(3), C, X) + rng.normal(0, setup.noise_sigma_px, (len(X), 2))
    R, t = relative_pose(pl, pr, K)
    # The camera orientation is R^T (camera -> world); truth: identity, centre (2, 0, 0).
    centre = -R.T @ t * setup.baseline_m
    Xe = _triangulate(K, R, t * setup.baseline_m, pl, pr)
    cos_t = float(centre @ C) / (np.linalg.norm(centre) * setup.baseline_m)
    return BasReliefRun(
        euler_error_deg=euler_xyz_deg(R.T),
        t_error_deg=float(np.degrees(np.arccos(np.clip(cos_t, -1, 1)))),
        points_true=X,
        points_est=Xe,
        depth_error=(Xe[:, 2] - X[:, 2]) / X[:, 2],
    )


@dataclass(frozen=True)
class BasReliefSummary:
    """Over ``runs`` simulations: |rotation error| about x, y, z (deg) as median, mean
    and 95th percentile; the share of runs whose baseline direction came out more than
    90 deg wrong; the median |relative depth error| of the points (median over runs)."""

    runs: int
    rot_median_deg: tuple[float, float, float]
    rot_mean_deg: tuple[float, float, float]
    rot_p95_deg: tuple[float, float, float]
    t_median_deg: float
    flipped_share: float
    depth_error_median: float


def run_many(
    setup: BasReliefSetup, runs: int, rng: np.random.Generator
) -> tuple[list[BasReliefRun], BasReliefSummary]:
    """``runs`` independent simulations and their summary."""
    results = [run_once(setup, rng) for _ in range(runs)]
    err = np.abs(np.array([r.euler_error_deg for r in results]))
    t_err = np.array([r.t_error_deg for r in results])

    def three(a: np.ndarray) -> tuple[float, float, float]:
        return (float(a[0]), float(a[1]), float(a[2]))

    summary = BasReliefSummary(
        runs=runs,
        rot_median_deg=three(np.median(err, axis=0)),
        rot_mean_deg=three(err.mean(axis=0)),
        rot_p95_deg=three(np.percentile(err, 95, axis=0)),
        t_median_deg=float(np.median(t_err)),
        flipped_share=float(np.mean(t_err > 90)),
        depth_error_median=float(np.median([np.median(np.abs(r.depth_error)) for r in results])),
    )
    return results, summary


def typical_run(results: list[BasReliefRun]) -> BasReliefRun:
    """The run with the median |y rotation error| among those whose baseline direction
    came out within ``GOOD_BASELINE_DEG`` (the paper's situation: translation nearly
    right); all runs if none did."""
    good = [r for r in results if r.t_error_deg < GOOD_BASELINE_DEG] or results
    y = np.abs([r.euler_error_deg[1] for r in good])
    return good[int(np.argsort(y)[len(y) // 2])]


def figure_png(results: list[BasReliefRun]) -> bytes:
    """Left: true and reconstructed points, top-down (x, z), of :func:`typical_run`
    (clipped to the true points' x range +-25 % and twice their z); right: histogram
    of the rotation error about y over all runs."""
    import io

    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(10, 4.2), dpi=120)
    FigureCanvasAgg(fig)
    ax, hx = fig.subplots(1, 2)
    run = typical_run(results)
    ax.scatter(run.points_true[:, 0], run.points_true[:, 2], s=2, label="true")
    ax.scatter(run.points_est[:, 0], run.points_est[:, 2], s=2, label="reconstructed")
    z_top = 2 * float(run.points_true[:, 2].max())
    x_lo, x_hi = float(run.points_true[:, 0].min()), float(run.points_true[:, 0].max())
    margin = 0.25 * (x_hi - x_lo)
    ax.set_xlim(x_lo - margin, x_hi + margin)
    ax.set_ylim(0, z_top)
    est = run.points_est
    shown = (est[:, 2] > 0) & (est[:, 2] < z_top)
    shown &= (est[:, 0] > x_lo - margin) & (est[:, 0] < x_hi + margin)
    off = int(np.count_nonzero(~shown))
    ax.set_xlabel(f"x (m); {off} reconstructed points outside the plot")
    ax.set_ylabel("z (m)")
    ax.set_title(
        f"median run of those with the baseline < {GOOD_BASELINE_DEG:.0f} deg off:\n"
        f"y rotation error {run.euler_error_deg[1]:+.3f} deg, "
        f"baseline {run.t_error_deg:.2f} deg off"
    )
    ax.legend(markerscale=4)
    y = [r.euler_error_deg[1] for r in results]
    hx.hist(y, bins=30)
    hx.axvline(0.207, color="black", linestyle="--", label="paper's run: 0.207 deg")
    hx.set_xlabel("rotation error about y (deg)")
    hx.set_ylabel("runs")
    hx.set_title(f"{len(results)} runs")
    hx.legend()
    fig.tight_layout()
    buf = io.BytesIO()
    fig.savefig(buf, format="png")
    return buf.getvalue()


def runs_csv(results: list[BasReliefRun]) -> str:
    """One line per run: Euler errors (deg), baseline direction error (deg), median
    |relative depth error| of the points."""
    lines = ["run,rot_x_deg,rot_y_deg,rot_z_deg,t_dir_deg,depth_error_median"]
    for i, r in enumerate(results):
        e = r.euler_error_deg
        lines.append(
            f"{i},{e[0]:.5f},{e[1]:.5f},{e[2]:.5f},{r.t_error_deg:.4f},"
            f"{float(np.median(np.abs(r.depth_error))):.5f}"
        )
    return "\n".join(lines) + "\n"
