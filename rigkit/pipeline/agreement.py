"""Stage 3b: where the three views disagree.

The three positions are captured minutes apart, and the world moves in between: cars
and people stand somewhere else in each view, appear or vanish, cloud shadows drift.
A disparity found on such a pixel is not a depth of anything, and semi-global matching
spreads it into its neighbours. Each depth is therefore checked against the views
that see it, as multi-view stereo checks photometric consistency (e.g. Schoenberger et
al., ECCV 2016, "Pixelwise view selection for unstructured multi-view stereo"):

* the right view: the disparity says where the pixel is in the rectified right image;
* the back view: the depth, with the back camera's pose from ambiguity removal, says
  where the pixel lands in the back image.

What the pixel looks like there is compared with what it looks like in the left view
by zero-mean normalised cross-correlation (ZNCC) over a small window: unmoved by the
gain and haze differences between cameras, and by a cloud shadow that darkens the
whole window alike. Only the pixels the other view sees enter the comparison, so a
window that straddles the edge of its frame or a hole in the disparity is judged on
its seen part. Where a view shows something else (low ZNCC), the pixel and a margin
around it get no depth.

Heat shimmer moves each view's patches by its own fraction of a pixel, so even a right
depth puts the other view's window off by that much, and fine texture decorrelates.
Where the views' measured misalignment (the back view's reprojection RMS from
ambiguity removal, the rectified rows' RMS for the right view) reaches
``SHIMMER_STEP_MIN_PX`` on the stereo canvas, each window is compared at its own
position and at one misalignment step around it, and the best score counts: midday air
(1 px of shimmer, single frames) had otherwise refused 14-24 % of the pixels, and the
refused matches were those the air had moved most, which left the offset's spread
under-estimated. Something that moved is metres away, far beyond one step.
"""

from __future__ import annotations

from collections.abc import Callable
from concurrent.futures import Future
from contextlib import nullcontext
from dataclasses import dataclass

import cv2
import numpy as np

from rigkit.core.threads import ViewPool
from rigkit.geometry import rotvec_to_matrix
from rigkit.pipeline.ambiguity import Ambiguity
from rigkit.pipeline.depth import triangulate_z
from rigkit.pipeline.lens import Lens
from rigkit.pipeline.rectify import Rectification, scaling
from rigkit.pipeline.rig import RigGeometry
from rigkit.pipeline.settings import PipelineSettings

CHUNK_ROWS = 64
"""Rows of the stereo canvas per chunk of :func:`back_positions`: its float64 arrays
(1.2 MB each at 2304 columns) stay in the cache."""


@dataclass(frozen=True)
class Agreement:
    """Result of :func:`view_agreement` on the ``scale``-resized rectified canvas.

    ``disagree``: (h, w) bool, pixels given no depth because a view disagrees (with
    the margin around them); ``right_ncc`` / ``back_ncc``: (h, w) float32 ZNCC of the
    left window with the right / back view's window where the depth puts it (1 =
    the same, NaN where that view has no window: no disparity, or outside it)."""

    disagree: np.ndarray
    right_ncc: np.ndarray
    back_ncc: np.ndarray

    def share(self, where: np.ndarray) -> float:
        """Fraction of the ``where`` pixels (h, w) bool that disagree."""
        n = int(where.sum())
        return float((self.disagree & where).sum() / n) if n else 0.0


MIN_SEEN_SHARE = 0.15
"""A window with fewer of its pixels seen by the other view than this share (12 of 81)
gives no evidence (NaN). Kept low on purpose: semi-global matching leaves what moved
riddled with holes, and the few disparities it does give there are the ones to judge
(on seven town scenes, 0.5 left up to 11.8 % of the moved pixels with a wrong depth,
0.15 up to 1.7 %; docs/pipeline.md, "Field conditions" 7)."""

SHIMMER_STEP_MIN_PX = 0.25
"""Per-axis RMS misalignment (stereo canvas px) from which a window is also compared
one step off its position: under it (field air of 0.3 px, bursts, still air) the
comparison is at the depth's own position only."""
SHIMMER_STEP_MAX_PX = 1.0
"""The step never exceeds this (stereo canvas px), whatever a poor fit's RMS says."""


def zncc(a: np.ndarray, b: np.ndarray, window: int) -> np.ndarray:
    """Zero-mean normalised cross-correlation of two (h, w) float32 images over a
    ``window`` x ``window`` box at every pixel, over only the pixels where ``b`` is
    finite (NaN: that view has nothing there): (h, w) float32 in [-1, 1]; 0 where
    either window is flat, NaN where ``b`` has under ``MIN_SEEN_SHARE`` of the window.

    Only the pixels both images have enter the sums. A window that straddles the edge
    of what a view sees (its frame, a pixel with no disparity) is compared on its seen
    part alone; filling the rest with ``a`` would mix two cameras' gains in one window
    and read as a change. Computed in place where it can be: every fresh image-sized
    array costs time to map in (docs/results-log.md, "Speed and memory")."""
    k = (window, window)
    seen = np.isfinite(b)
    w = seen.astype(np.float32)
    b0 = np.where(seen, b, np.float32(0))
    a0 = a * w
    n = cv2.boxFilter(w, -1, k)  # the seen share of each window
    ma, mb = cv2.boxFilter(a0, -1, k), cv2.boxFilter(b0, -1, k)
    np.multiply(a0, a, out=w)
    saa = cv2.boxFilter(w, -1, k)
    np.multiply(b0, b0, out=w)
    sbb = cv2.boxFilter(w, -1, k)
    np.multiply(a0, b0, out=w)
    cov = cv2.boxFilter(w, -1, k)
    few = n < MIN_SEEN_SHARE
    np.maximum(n, MIN_SEEN_SHARE, out=n)
    for sums in (ma, mb, saa, sbb, cov):  # box means over all pixels -> over the seen
        np.divide(sums, n, out=sums)
    cov -= np.multiply(ma, mb, out=w)  # w, the products' buffer, is free from here on
    saa -= np.multiply(ma, ma, out=w)
    sbb -= np.multiply(mb, mb, out=w)
    np.maximum(saa, 0, out=saa)  # rounding can make a flat window's variance negative
    np.maximum(sbb, 0, out=sbb)
    den = np.sqrt(saa * sbb, out=saa)
    flat = den <= 1e-6
    np.divide(cov, np.maximum(den, 1e-6, out=den), out=cov)
    np.copyto(cov, 0.0, where=flat)  # copyto: 4x a boolean index
    np.copyto(cov, np.nan, where=few)
    return cov


def right_at_disparity(right: np.ndarray, disparity: np.ndarray, dy: float = 0.0,
                       first_row: int = 0) -> np.ndarray:
    """The rectified right image (H, w) float32 sampled where each left pixel's
    disparity (px, ``x_left - x_right``; (h, w), the canvas's rows from ``first_row``)
    puts its match, ``dy`` px lower: (h, w) float32, NaN where the disparity is NaN or
    the match is off the image."""
    h, w = disparity.shape
    xs = (np.arange(w, dtype=np.float32)[None, :] - disparity).astype(np.float32, copy=False)
    ys = np.broadcast_to(np.arange(first_row, first_row + h, dtype=np.float32)[:, None]
                         + np.float32(dy), (h, w))
    return cv2.remap(right, xs, np.ascontiguousarray(ys), cv2.INTER_LINEAR,
                     borderMode=cv2.BORDER_CONSTANT, borderValue=np.nan)


def _resized(image: np.ndarray, scale: float) -> np.ndarray:
    """``image`` area-averaged to ``scale`` (the stereo canvas's pixel size)."""
    small = (round(image.shape[1] * scale), round(image.shape[0] * scale))
    return cv2.resize(image, small, interpolation=cv2.INTER_AREA)


def _sample(image: np.ndarray, xs: np.ndarray, ys: np.ndarray) -> np.ndarray:
    """``image`` at (xs, ys) (float32 maps), bilinear, NaN outside it."""
    return cv2.remap(image, xs, ys, cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT,
                     borderValue=np.nan)


def back_positions(
    disparity: np.ndarray, scale: float, rect: Rectification, amb: Ambiguity, lens: Lens,
    baseline_lr_m: float, baseline_lb_m: float, pool: ViewPool | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Where each pixel of the ``scale``-resized rectified left canvas lands in the
    ``scale``-resized recorded back image, given its disparity (px on that canvas,
    ``x_left - x_right``) and the geometry fitted by ambiguity removal: (x, y), each
    (h, w) float32 px; NaN where there is no disparity. Chunks of ``CHUNK_ROWS`` rows
    side by side in ``pool`` (None: a pool of its own)."""
    h, w = disparity.shape
    S, Sinv = scaling(scale), np.linalg.inv(scaling(scale))
    f = rect.K[0, 0]
    cx, cy = rect.K[0, 2] + rect.canvas[0, 2], rect.K[1, 2] + rect.canvas[1, 2]
    # A rectified pixel's ray (a, p, 1) (left frame: R_rect^T of it) in the back
    # camera's axes is linear in (u, v): q = R_b R_rect^T (a, p, 1).
    M = rotvec_to_matrix(amb.back_rotvec) @ rect.R_rect.T
    t = rotvec_to_matrix(amb.back_rotvec) @ np.array([*amb.back_offset_m, -baseline_lb_m])
    xs, ys = np.empty((h, w), np.float32), np.empty((h, w), np.float32)
    u = Sinv[0, 0] * np.arange(w) + Sinv[0, 2]
    a = (u - cx) / f

    def chunk(r0: int) -> None:
        rows = slice(r0, min(r0 + CHUNK_ROWS, h))
        v = Sinv[1, 1] * np.arange(rows.start, rows.stop) + Sinv[1, 2]
        p = ((v - cy) / f)[:, None]
        d = disparity[rows].astype(np.float64)
        d /= scale
        z = triangulate_z(rect, u[None, :], d, amb.beta, baseline_lr_m)
        X = [M[i, 0] * a[None, :] + M[i, 1] * p + M[i, 2] for i in range(3)]  # q
        for i in range(3):  # X = z q - t, in place
            np.multiply(z, X[i], out=X[i])
            X[i] -= t[i]
        with np.errstate(divide="ignore", invalid="ignore"):
            for i in range(2):  # X / X_z f + c, in place
                np.divide(X[i], X[2], out=X[i])
                X[i] *= f
                X[i] += rect.K[i, 2]
        ideal = np.stack(X[:2], axis=-1)
        rec = lens.to_recorded(ideal)
        xs[rows] = S[0, 0] * rec[..., 0] + S[0, 2]
        ys[rows] = S[1, 1] * rec[..., 1] + S[1, 2]

    with ViewPool() if pool is None else nullcontext(pool) as run:
        run.map(chunk, range(0, h, CHUNK_ROWS))
    return xs, ys


def shimmer_steps(rms_px: float, scale: float, axes: int) -> list[tuple[float, float]]:
    """The offsets (dx, dy) (stereo canvas px) at which a window is compared: only
    (0, 0) where the per-axis misalignment ``rms_px`` (full-resolution px, one axis)
    times ``scale`` is under ``SHIMMER_STEP_MIN_PX``; else one step of it (at most
    ``SHIMMER_STEP_MAX_PX``) each way along y (``axes`` 1) or along x and y (2)."""
    step = min(rms_px * scale, SHIMMER_STEP_MAX_PX)
    if not step >= SHIMMER_STEP_MIN_PX:
        return [(0.0, 0.0)]
    offsets = (-step, 0.0, step)
    if axes == 1:
        return [(0.0, dy) for dy in offsets]
    return [(dx, dy) for dy in offsets for dx in offsets]


def view_agreement(
    left: np.ndarray, right: np.ndarray, back: np.ndarray, disparity: np.ndarray,
    scale: float, rect: Rectification, amb: Ambiguity, lens: Lens, rig: RigGeometry,
    settings: PipelineSettings,
) -> Agreement:
    """Pixels of the rectified left canvas whose depth the right or the back view
    contradicts: ZNCC over ``settings.agreement_window_px`` px below
    ``settings.min_agreement`` in either view, grown by ``settings.agreement_margin_px``
    px (semi-global matching has spread a wrong disparity that far). Each view's window
    is taken at the best of :func:`shimmer_steps` around where the depth puts it (module
    docstring).

    left, right: (h, w) float32 rectified pair at ``scale`` (:func:`warp_pair`);
    back: (H, W) float32 recorded back image; disparity: (h, w) float32 px at
    ``scale``, ``x_left - x_right``, NaN = none; ``amb``: the back camera's pose;
    ``rig``: its baselines place the back view's windows."""
    window, min_ncc = settings.agreement_window_px, settings.min_agreement
    margin = settings.agreement_margin_px
    known = np.isfinite(disparity)
    right_steps = shimmer_steps(rect.row_rms_px, scale, axes=1)
    back_steps = shimmer_steps(amb.rms_px / np.sqrt(2), scale, axes=2)  # 2-D RMS per axis

    def right_view(dx: float, dy: float, rows: slice) -> np.ndarray:
        return right_at_disparity(right, disparity[rows], dy, rows.start)

    # Each view's comparison at each offset, band by band, is a task of its own,
    # collected in order.
    with ViewPool() as pool:
        back_small = pool.submit(_resized, back, scale)
        right_scores = _scores(pool, left, right_view, right_steps, known, window)
        xs, ys = back_positions(disparity, scale, rect, amb, lens, rig.baseline_lr_m,
                                rig.baseline_lb_m, pool)
        small = back_small.result()

        def back_view(dx: float, dy: float, rows: slice) -> np.ndarray:
            return _sample(small, xs[rows] + np.float32(dx), ys[rows] + np.float32(dy))

        back_scores = _scores(pool, left, back_view, back_steps, known, window)
        ncc = [_best(right_scores, left.shape), _best(back_scores, left.shape)]
    with np.errstate(invalid="ignore"):
        bad = (ncc[0] < min_ncc) | (ncc[1] < min_ncc)
    if margin:
        kernel = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * margin + 1,) * 2)
        bad = cv2.dilate(bad.astype(np.uint8), kernel) > 0
    return Agreement(bad, ncc[0], ncc[1])


SCORE_ROWS = 256
"""Rows of the canvas per band of a view's comparison (:func:`_scores`)."""

Sample = Callable[[float, float, slice], np.ndarray]
"""What a view shows where the depth puts each pixel of the canvas's ``rows`` (a slice),
moved by (dx, dy) px: (h, w) float32, NaN where the view has nothing."""
Scores = list[tuple[slice, list[Future[np.ndarray]]]]
"""Bands of the canvas's rows, each with a view's :func:`_score` there at each offset."""


def _scores(
    pool: ViewPool, left: np.ndarray, sample: Sample, steps: list[tuple[float, float]],
    known: np.ndarray, window: int,
) -> Scores:
    """A view's comparison with ``left`` (h, w) at each of ``steps``, in bands of
    ``SCORE_ROWS`` rows, each band's windows taken on the band and half a window more
    each side (a window's sums are its own pixels': the same as on the whole canvas),
    as tasks of ``pool``."""
    h, half = left.shape[0], window // 2
    scores: Scores = []
    for r0 in range(0, h, SCORE_ROWS):
        band = slice(r0, min(r0 + SCORE_ROWS, h))
        rows = slice(max(r0 - half, 0), min(band.stop + half, h))
        keep = slice(r0 - rows.start, band.stop - rows.start)
        scores.append((band, [pool.submit(_score, left[rows], sample, step, known[rows],
                                          window, rows, keep) for step in steps]))
    return scores


def _score(
    left: np.ndarray, sample: Sample, step: tuple[float, float], known: np.ndarray,
    window: int, rows: slice, keep: slice,
) -> np.ndarray:
    """The ZNCC of ``left`` (the canvas's ``rows``) with what a view shows where the
    depth puts each pixel, moved by one ``step`` (dx, dy) of :func:`shimmer_steps`
    (``sample``): float32, NaN where the view does not see the pixel, of the rows
    ``keep`` of ``rows``. A pixel without a disparity (``known`` False) is no evidence;
    nor is one the view does not see."""
    seen = sample(*step, rows)
    np.copyto(seen, np.nan, where=~known)
    score = zncc(left, seen, window)
    np.copyto(score, np.nan, where=np.isnan(seen))
    return score[keep]


def _best(scores: Scores, shape: tuple[int, ...]) -> np.ndarray:
    """The best of a view's :func:`_scores` at each offset, band by band, taken in the
    order given (each dropped once taken): ``shape`` float32, NaN where no offset has a
    seen window."""
    best = np.empty(shape, np.float32)
    for band, futures in scores:
        np.copyto(best[band], futures.pop(0).result())
        while futures:
            np.fmax(best[band], futures.pop(0).result(), out=best[band])
    return best
