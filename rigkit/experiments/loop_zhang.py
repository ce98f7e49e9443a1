"""The Loop-Zhang baseline: uncalibrated rectification from a fundamental matrix.

* Fundamental matrix by RANSAC over samples of 8 matches with Hartley's normalised
  8-point algorithm (Hartley & Zisserman, Multiple View Geometry, alg. 11.1 and 11.4),
  Sampson error as the inlier test, refitted on the inliers.
* Rectifying homographies after Loop & Zhang, "Computing rectifying homographies for
  stereo vision" (CVPR 1999): ``H = H_s H_r H_p`` per image, where the projective part
  ``H_p`` (last row ``w``) sends the epipole to infinity with ``w = [e]_x z`` and
  ``w' = F z`` for one ``z = (cos t, sin t, 0)`` that keeps both images least
  projectively distorted (their ratio-of-quadratic-forms criterion, minimised over t);
  the similarity ``H_r`` turns the epipoles onto the x axis and aligns rows
  (``F = w' v^T - v' w^T`` gives the second rows ``v``, ``v'``); the shear ``H_s``
  restores perpendicularity and aspect ratio of the image's mid-lines. Both images get
  the same uniform scale, so that the left image keeps its area.

Then the same stereo matcher, the paper's ambiguity removal and Eq. 5 (as in the
paper's comparison, sec. 5.2).
"""

from __future__ import annotations

import numpy as np
from scipy.optimize import minimize_scalar

from rigkit.errors import PipelineError
from rigkit.experiments.common import RectifiedPair, apply_h, dense_disparity, on_canvas
from rigkit.experiments.paper import PaperSettings, depth_from_offset, pair_median_offset
from rigkit.pipeline.features import Matches
from rigkit.pipeline.stereo import StereoMatcher

SAMPSON_PX = 1.0  # inlier threshold of the fundamental-matrix RANSAC
F_TRIALS = 2000


def _normaliser(p: np.ndarray) -> np.ndarray:
    """Similarity moving (N, 2) points to centroid 0 and mean distance sqrt(2)."""
    c = p.mean(axis=0)
    s = np.sqrt(2) / max(float(np.mean(np.linalg.norm(p - c, axis=1))), 1e-12)
    return np.array([[s, 0, -s * c[0]], [0, s, -s * c[1]], [0, 0, 1.0]])


def eight_point(pl: np.ndarray, pr: np.ndarray) -> np.ndarray:
    """Normalised 8-point fundamental matrix (3, 3), rank 2, ``x_r^T F x_l = 0``,
    from >= 8 matches ``pl`` <-> ``pr`` ((N, 2) px), scaled to unit Frobenius norm."""
    Tl, Tr = _normaliser(pl), _normaliser(pr)
    a, b = apply_h(Tl, pl), apply_h(Tr, pr)
    A = np.column_stack(
        [b[:, :1] * a, b[:, :1], b[:, 1:] * a, b[:, 1:], a, np.ones(len(a))]
    )
    F = np.linalg.svd(A)[2][-1].reshape(3, 3)
    U, s, Vt = np.linalg.svd(F)
    F = Tr.T @ (U @ np.diag([s[0], s[1], 0.0]) @ Vt) @ Tl
    return F / np.linalg.norm(F)


def sampson(F: np.ndarray, pl: np.ndarray, pr: np.ndarray) -> np.ndarray:
    """First-order geometric error (px) of each match under F, (N,)."""
    xl = np.column_stack([pl, np.ones(len(pl))])
    xr = np.column_stack([pr, np.ones(len(pr))])
    Fx, Ftx = xl @ F.T, xr @ F
    num = np.einsum("ij,ij->i", xr, Fx) ** 2
    den = Fx[:, 0] ** 2 + Fx[:, 1] ** 2 + Ftx[:, 0] ** 2 + Ftx[:, 1] ** 2
    return np.sqrt(num / np.maximum(den, 1e-300))


def fundamental_ransac(
    pl: np.ndarray, pr: np.ndarray, rng: np.random.Generator, trials: int = F_TRIALS
) -> tuple[np.ndarray, np.ndarray]:
    """RANSAC normalised 8-point: (F (3, 3), inlier mask (N,) bool)."""
    best = np.zeros(len(pl), bool)
    for _ in range(trials):
        pick = rng.choice(len(pl), 8, replace=False)
        inl = sampson(eight_point(pl[pick], pr[pick]), pl, pr) < SAMPSON_PX
        if inl.sum() > best.sum():
            best = inl
    if best.sum() < 8:
        raise PipelineError("loop-zhang: RANSAC found no fundamental matrix")
    return eight_point(pl[best], pr[best]), best


def _cross(e: np.ndarray) -> np.ndarray:
    return np.array([[0, -e[2], e[1]], [e[2], 0, -e[0]], [-e[1], e[0], 0.0]])


def _distortion_forms(size: tuple[int, int]) -> tuple[np.ndarray, np.ndarray]:
    """Loop & Zhang's ``P P^T`` and ``p_c p_c^T`` (3, 3) for a w x h image."""
    w, h = size
    PPt = w * h / 12.0 * np.diag([w * w - 1.0, h * h - 1.0, 0.0])
    pc = np.array([(w - 1) / 2, (h - 1) / 2, 1.0])
    return PPt, np.outer(pc, pc)


def _projective_rows(F: np.ndarray, size: tuple[int, int]) -> tuple[np.ndarray, np.ndarray]:
    """Last rows ``w``, ``w'`` (3,) of the projective parts, normalised to w_3 = 1."""
    e = np.linalg.svd(F)[2][-1]  # F e = 0: the epipole in the left image
    ex = _cross(e)
    PPt, pcpc = _distortion_forms(size)

    def distortion(t: float) -> float:
        z = np.array([np.cos(t), np.sin(t), 0.0])
        ws = (ex @ z, F @ z)
        den = [float(w @ pcpc @ w) for w in ws]
        # w . p_c = 0 sends the image centre to infinity: not a candidate.
        if min(den) <= 1e-12 * max(max(den), 1e-300):
            return np.inf
        return sum(float(w @ PPt @ w) / d for w, d in zip(ws, den, strict=True))

    grid = np.linspace(0, np.pi, 721)
    t0 = grid[int(np.argmin([distortion(t) for t in grid]))]
    step = grid[1]
    t = minimize_scalar(distortion, bounds=(t0 - step, t0 + step), method="bounded").x
    z = np.array([np.cos(t), np.sin(t), 0.0])
    w, w2 = ex @ z, F @ z
    return w / w[2], w2 / w2[2]


def _shear(H: np.ndarray, size: tuple[int, int]) -> np.ndarray:
    """Loop & Zhang's shear (3, 3) keeping the mid-lines of the image, mapped by ``H``,
    perpendicular and in the image's aspect ratio."""
    w, h = size
    mid = np.array([[(w - 1) / 2, 0], [w - 1, (h - 1) / 2], [(w - 1) / 2, h - 1], [0, (h - 1) / 2]])
    a, b, c, d = apply_h(H, mid)
    x, y = b - d, c - a
    den = h * w * (x[1] * y[0] - x[0] * y[1])
    sa = (h * h * x[1] ** 2 + w * w * y[1] ** 2) / den
    sb = -(h * h * x[0] * x[1] + w * w * y[0] * y[1]) / den
    if sa < 0:  # both conditions hold for (-sa, -sb) too; keep the one that does not mirror
        sa, sb = -sa, -sb
    return np.array([[sa, sb, 0], [0, 1, 0], [0, 0, 1.0]])


def rectifying_homographies(
    F: np.ndarray, size: tuple[int, int]
) -> tuple[np.ndarray, np.ndarray]:
    """Loop-Zhang homographies (H_left, H_right), (3, 3) each, for ``x_r^T F x_l = 0``
    and images of ``size`` = (w, h) px: matched points end on the same row."""
    w, w2 = _projective_rows(F, size)
    Hp = np.array([[1, 0, 0], [0, 1, 0], [w[0], w[1], 1.0]])
    Hp2 = np.array([[1, 0, 0], [0, 1, 0], [w2[0], w2[1], 1.0]])
    if F[2, 1] - w[1] * F[2, 2] < 0:
        F = -F  # the other sign turns both images upside down
    Hr = np.array(
        [
            [F[2, 1] - w[1] * F[2, 2], w[0] * F[2, 2] - F[2, 0], 0],
            [F[2, 0] - w[0] * F[2, 2], F[2, 1] - w[1] * F[2, 2], F[2, 2]],
            [0, 0, 1.0],
        ]
    )
    Hr2 = np.array(
        [
            [w2[1] * F[2, 2] - F[1, 2], F[0, 2] - w2[0] * F[2, 2], 0],
            [w2[0] * F[2, 2] - F[0, 2], w2[1] * F[2, 2] - F[1, 2], 0],
            [0, 0, 1.0],
        ]
    )
    H_l, H_r = Hr @ Hp, Hr2 @ Hp2
    H_l, H_r = _shear(H_l, size) @ H_l, _shear(H_r, size) @ H_r
    wd, ht = size
    quad = apply_h(H_l, np.array([[0, 0], [wd - 1, 0], [wd - 1, ht - 1], [0, ht - 1]], float))
    x, y = quad[:, 0], quad[:, 1]
    area = 0.5 * abs(float(x @ np.roll(y, -1) - y @ np.roll(x, -1)))
    S = np.diag([1.0, 1.0, 1.0])
    S[:2, :2] *= np.sqrt((wd - 1) * (ht - 1) / area)
    return S @ H_l, S @ H_r


def loop_zhang_rectify(
    m_lr: Matches, image_size: tuple[int, int], rng: np.random.Generator
) -> RectifiedPair:
    """F by RANSAC from left/right matches, Loop-Zhang homographies, on a canvas."""
    F, inl = fundamental_ransac(m_lr.left, m_lr.other, rng)
    H_l, H_r = rectifying_homographies(F, image_size)
    return on_canvas(H_l, H_r, image_size, m_lr.left[inl], m_lr.other[inl])


def loop_zhang_depth(
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
    """Depth of the left view (H, W) float32, metres: Loop-Zhang rectification, then the
    paper's stereo, ambiguity removal and Eq. 5. Raises PipelineError on failure."""
    settings = settings or PaperSettings()
    pair = loop_zhang_rectify(m_lr, (left.shape[1], left.shape[0]), rng)
    disparity = dense_disparity(left, right, pair, matcher)
    q, _ = pair_median_offset(
        m_lb, disparity, pair, f_px, c_lr, c_lb, settings, left.shape[1], rng
    )
    return depth_from_offset(disparity, pair, q, f_px, c_lr, left.shape)
