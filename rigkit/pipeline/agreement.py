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
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from rigkit.geometry import rotvec_to_matrix
from rigkit.pipeline.ambiguity import Ambiguity
from rigkit.pipeline.depth import triangulate_z
from rigkit.pipeline.lens import Lens
from rigkit.pipeline.rectify import Rectification, scaling

CHUNK_ROWS = 256


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


def zncc(a: np.ndarray, b: np.ndarray, window: int) -> np.ndarray:
    """Zero-mean normalised cross-correlation of two (h, w) float32 images over a
    ``window`` x ``window`` box at every pixel, over only the pixels where ``b`` is
    finite (NaN: that view has nothing there): (h, w) float32 in [-1, 1]; 0 where
    either window is flat, NaN where ``b`` has under ``MIN_SEEN_SHARE`` of the window.

    Only the pixels both images have enter the sums. A window that straddles the edge
    of what a view sees (its frame, a pixel with no disparity) is compared on its seen
    part alone; filling the rest with ``a`` would mix two cameras' gains in one window
    and read as a change. Computed in place where it can be: every fresh image-sized
    array costs time to map in (docs/results.md, "Speed and memory")."""
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
    cov -= ma * mb
    saa -= ma * ma
    sbb -= mb * mb
    np.maximum(saa, 0, out=saa)  # rounding can make a flat window's variance negative
    np.maximum(sbb, 0, out=sbb)
    den = np.sqrt(saa * sbb, out=saa)
    flat = den <= 1e-6
    np.divide(cov, np.maximum(den, 1e-6, out=den), out=cov)
    cov[flat] = 0.0
    cov[few] = np.nan
    return cov


def right_at_disparity(right: np.ndarray, disparity: np.ndarray) -> np.ndarray:
    """The rectified right image (h, w) float32 sampled where each left pixel's
    disparity (px, ``x_left - x_right``) puts its match: (h, w) float32, NaN where
    the disparity is NaN or the match is off the image."""
    h, w = disparity.shape
    xs = (np.arange(w, dtype=np.float32)[None, :] - disparity).astype(np.float32)
    ys = np.broadcast_to(np.arange(h, dtype=np.float32)[:, None], (h, w))
    return cv2.remap(right, xs, np.ascontiguousarray(ys), cv2.INTER_LINEAR,
                     borderMode=cv2.BORDER_CONSTANT, borderValue=np.nan)


def back_at_depth(
    back: np.ndarray, disparity: np.ndarray, scale: float, rect: Rectification,
    amb: Ambiguity, lens: Lens, baseline_lr_m: float, baseline_lb_m: float,
) -> np.ndarray:
    """The back image sampled where each pixel of the ``scale``-resized rectified left
    canvas lands in it, given its disparity (px on that canvas, ``x_left - x_right``)
    and the geometry fitted by ambiguity removal: (h, w) float32, NaN where there is
    no disparity or the point falls outside the back image.

    back: (H, W) float32, the recorded back image at full resolution."""
    h, w = disparity.shape
    small = (round(back.shape[1] * scale), round(back.shape[0] * scale))
    back_small = cv2.resize(back, small, interpolation=cv2.INTER_AREA)
    S, Sinv = scaling(scale), np.linalg.inv(scaling(scale))
    f = rect.K[0, 0]
    cx, cy = rect.K[0, 2] + rect.canvas[0, 2], rect.K[1, 2] + rect.canvas[1, 2]
    # A rectified pixel's ray (a, p, 1) (left frame: R_rect^T of it) in the back
    # camera's axes is linear in (u, v): q = R_b R_rect^T (a, p, 1).
    M = rotvec_to_matrix(amb.back_rotvec) @ rect.R_rect.T
    t = rotvec_to_matrix(amb.back_rotvec) @ np.array([*amb.back_offset_m, -baseline_lb_m])
    out = np.empty((h, w), np.float32)
    u = Sinv[0, 0] * np.arange(w) + Sinv[0, 2]
    a = (u - cx) / f
    for r0 in range(0, h, CHUNK_ROWS):
        rows = slice(r0, min(r0 + CHUNK_ROWS, h))
        v = Sinv[1, 1] * np.arange(rows.start, rows.stop) + Sinv[1, 2]
        p = ((v - cy) / f)[:, None]
        d = disparity[rows].astype(np.float64) / scale
        z = triangulate_z(rect, u[None, :], d, amb.beta, baseline_lr_m)
        q = [M[i, 0] * a[None, :] + M[i, 1] * p + M[i, 2] for i in range(3)]
        X = [z * q[i] - t[i] for i in range(3)]
        with np.errstate(divide="ignore", invalid="ignore"):
            ideal = np.stack([X[0] / X[2] * f + rect.K[0, 2], X[1] / X[2] * f + rect.K[1, 2]],
                             axis=-1)
        rec = lens.to_recorded(ideal)
        xs = (S[0, 0] * rec[..., 0] + S[0, 2]).astype(np.float32)
        ys = (S[1, 1] * rec[..., 1] + S[1, 2]).astype(np.float32)
        out[rows] = cv2.remap(back_small, xs, ys, cv2.INTER_LINEAR,
                              borderMode=cv2.BORDER_CONSTANT, borderValue=np.nan)
    return out


def view_agreement(
    left: np.ndarray, right: np.ndarray, back: np.ndarray, disparity: np.ndarray,
    scale: float, rect: Rectification, amb: Ambiguity, lens: Lens,
    baseline_lr_m: float, baseline_lb_m: float, min_ncc: float, window: int, margin: int,
) -> Agreement:
    """Pixels of the rectified left canvas whose depth the right or the back view
    contradicts: ZNCC over ``window`` px below ``min_ncc`` in either view, grown by
    ``margin`` px (semi-global matching has spread a wrong disparity that far).

    left, right: (h, w) float32 rectified pair at ``scale`` (:func:`warp_pair`);
    back: (H, W) float32 recorded back image; disparity: (h, w) float32 px at
    ``scale``, ``x_left - x_right``, NaN = none; ``amb``: the back camera's pose."""
    known = np.isfinite(disparity)
    ncc = []
    for seen in (right_at_disparity(right, disparity),
                 back_at_depth(back, disparity, scale, rect, amb, lens,
                               baseline_lr_m, baseline_lb_m)):
        # A pixel the view does not see (no disparity, outside its frame) is no evidence.
        seen[~known] = np.nan
        score = zncc(left, seen, window)
        score[np.isnan(seen)] = np.nan
        ncc.append(score)
    with np.errstate(invalid="ignore"):
        bad = (ncc[0] < min_ncc) | (ncc[1] < min_ncc)
    if margin:
        kernel = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * margin + 1,) * 2)
        bad = cv2.dilate(bad.astype(np.uint8), kernel) > 0
    return Agreement(bad, ncc[0], ncc[1])
