"""Heat shimmer measured from two frames of one camera position.

Two frames of a burst differ by the tripod's sway, a global shift and turn, and by
the shimmer of each frame: a smooth random displacement field, drawn afresh every few
milliseconds. Points tracked from the first frame to the other, less a global affine
map, move by ``r(p) = s_2(p) - s_1(p) + e``, where ``e`` is the tracker's own error.
Its semivariogram, per axis,

    gamma(h) = 1/2 E[(r(p + h) - r(p))^2] = n^2 + 2 s^2 (1 - exp(-h^2 / (4 c^2))),

rises from the tracker's noise ``n`` between neighbouring points to the shimmer's
variance, twice one frame's ``s^2``, between points farther apart than its patches.
Fitting it (Matheron's variogram, as in geostatistics) separates the shimmer from the
tracker without knowing either. ``c`` is the Gaussian correlation length the
synthetic scenes draw their shimmer with (:func:`rigkit.synth.shimmer.shimmer_field`);
real turbulence has a longer tail, so for it ``c`` is the best Gaussian match.

The measurement runs on the most textured crop at full resolution: shimmer of a few tenths of
a pixel would be lost in a reduced image, and its statistics are the same across the
frame.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import cv2
import numpy as np

from rigkit.core.lazy import function
from rigkit.core.threads import deterministic
from rigkit.errors import PipelineError
from rigkit.pipeline.burst import frame_shift, textured_crop

least_squares = function("scipy.optimize", "least_squares")
pdist = function("scipy.spatial.distance", "pdist")

CROP_PX = 2048  # side of the (most textured) crop measured on, full-resolution px
MAX_POINTS = 2000  # points tracked between the frames
FB_MAX_PX = 0.1  # forward-backward disagreement above which a track is dropped
MIN_POINTS = 100
BIN_PX = 8.0  # distance bins of the semivariogram
MIN_SHIMMER_PX = 0.02  # below this, no correlation length is reported


@dataclass(frozen=True)
class Shimmer:
    """Heat shimmer of one frame, measured from two: ``rms_px`` RMS image displacement
    per axis (px); ``corr_px`` its correlation length ``c`` (px: the correlation
    between points ``h`` apart is exp(-h^2 / 4 c^2), as for white noise blurred by a
    Gaussian of sigma ``c``; NaN where there is too little shimmer to tell);
    ``tracker_px`` the tracking noise per axis the fit separated from it; ``points``
    tracked points it rests on."""

    rms_px: float
    corr_px: float
    tracker_px: float
    points: int

    def as_dict(self) -> dict[str, float | int | None]:
        """Plain data for depth.json (an unknown correlation length as null)."""
        corr = self.corr_px if math.isfinite(self.corr_px) else None
        return {"rms_px": self.rms_px, "corr_px": corr, "tracker_px": self.tracker_px,
                "points": self.points}


@dataclass(frozen=True)
class ShimmerStart:
    """The first of two frames as :func:`measure_shimmer` takes it, the same against
    every other frame of its burst: ``shape`` (H, W) of the frame, ``where`` its most
    textured crop (rows, columns), ``crop`` that crop as (h, w) uint8, ``points``
    (N, 1, 2) float32 the corners of the crop that are tracked, crop px."""

    shape: tuple[int, ...]
    where: tuple[slice, slice]
    crop: np.ndarray
    points: np.ndarray


@deterministic
def measure_shimmer(first: np.ndarray, other: np.ndarray, what: str = "burst") -> Shimmer:
    """:class:`Shimmer` from two (H, W) float32 grey frames of one camera position at
    full resolution (``what`` names them in errors). Raises PipelineError where the
    frames have too little texture to track or do not show the same view."""
    return shimmer_from(shimmer_start(first, what), other, what)


def shimmer_start(first: np.ndarray, what: str = "burst") -> ShimmerStart:
    """The (H, W) float32 ``first`` frame prepared for :func:`shimmer_from`; PipelineError
    where it has too little texture to track."""
    where = textured_crop(first, CROP_PX)
    a = _crop(first, where)
    spacing = max(4.0, 0.7 * math.sqrt(a.size / MAX_POINTS))
    found = cv2.goodFeaturesToTrack(a, MAX_POINTS, 0.005, spacing, blockSize=5)
    if found is None or len(found) < MIN_POINTS:
        raise PipelineError(f"{what}: too little texture to measure heat shimmer")
    return ShimmerStart(first.shape, where, a, found.reshape(-1, 1, 2).astype(np.float32))


@deterministic
def shimmer_from(start: ShimmerStart, other: np.ndarray, what: str = "burst") -> Shimmer:
    """:func:`measure_shimmer` from its first frame's ``start`` and the (H, W) float32
    ``other`` frame."""
    if start.shape != other.shape:
        raise PipelineError(f"{what}: frames of different sizes")
    begin, moved = _tracks(start, _crop(other, start.where), what)
    points, residual = _less_global_map(begin, moved, what)
    distance, gamma = pdist(points), 0.25 * pdist(residual, "sqeuclidean")
    # (1/4 of the squared distance: half the mean over the two axes)
    return _fit(distance, gamma, len(points), max_distance=min(start.crop.shape) / 3)


def burst_shimmer(
    frames: Sequence[np.ndarray], position: str
) -> tuple[Shimmer, str] | None:
    """:func:`measure_shimmer` between the first two of a position's ``frames`` and which
    they were ("left frames 1 and 2"); None for a single frame, or where the frames
    cannot be tracked (the field checks say why as the frames are taken)."""
    if len(frames) < 2:
        return None
    where = f"{position} frames 1 and 2"
    try:
        return measure_shimmer(frames[0], frames[1], where), where
    except PipelineError:
        return None


def _crop(image: np.ndarray, where: tuple[slice, slice]) -> np.ndarray:
    return np.clip(np.rint(image[where]), 0, 255).astype(np.uint8)


def _tracks(start: ShimmerStart, b: np.ndarray, what: str) -> tuple[np.ndarray, np.ndarray]:
    """(N, 2) float64 points of the first frame's crop (``start``) and where they are in
    ``b``, the other frame's, checked both ways."""
    a, p0 = start.crop, start.points
    dx, dy = frame_shift(a.astype(np.float32), b.astype(np.float32))
    p1, st1 = _follow(a, b, p0, p0 + np.array([dx, dy], np.float32))
    back, st2 = _follow(b, a, p1, p0.copy())
    h, w = a.shape
    ok = (st1.ravel() == 1) & (st2.ravel() == 1)
    ok &= np.linalg.norm((back - p0).reshape(-1, 2), axis=1) < FB_MAX_PX
    q = p1.reshape(-1, 2)
    ok &= (q[:, 0] > 10) & (q[:, 0] < w - 11) & (q[:, 1] > 10) & (q[:, 1] < h - 11)
    if ok.sum() < MIN_POINTS:
        raise PipelineError(
            f"{what}: only {int(ok.sum())} points could be followed from one frame to the "
            f"next (need {MIN_POINTS}); are both frames of the same view?"
        )
    return p0.reshape(-1, 2)[ok].astype(np.float64), q[ok].astype(np.float64)


def _follow(
    a: np.ndarray, b: np.ndarray, points: np.ndarray, guess: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Pyramidal Lucas-Kanade of (N, 1, 2) float32 ``points`` from ``a`` to ``b``,
    starting at ``guess``: (where they are in ``b``, status)."""
    crit = (cv2.TERM_CRITERIA_EPS | cv2.TERM_CRITERIA_COUNT, 40, 0.005)
    moved, status, _ = cv2.calcOpticalFlowPyrLK(
        a, b, points, guess, winSize=(21, 21), maxLevel=3,
        criteria=crit, flags=cv2.OPTFLOW_USE_INITIAL_FLOW,
    )
    return moved, status


def _less_global_map(
    start: np.ndarray, moved: np.ndarray, what: str
) -> tuple[np.ndarray, np.ndarray]:
    """The points and what is left of each one's move, (N, 2) each, after a global
    affine map, the tripod's sway: fitted robustly, then by least squares on the points
    it explains (the others, mistracked, are dropped)."""
    A, _ = cv2.estimateAffine2D(start, moved, method=cv2.LMEDS)
    if A is None:
        raise PipelineError(f"{what}: the frames do not show the same view")
    size = np.linalg.norm(moved - (start @ A[:, :2].T + A[:, 2]), axis=1)
    keep = size < 5 * 1.4826 * float(np.median(size)) + 1e-9
    if keep.sum() < MIN_POINTS:
        raise PipelineError(f"{what}: the frames do not show the same view")
    X = np.hstack([start[keep], np.ones((int(keep.sum()), 1))])
    coef, *_ = np.linalg.lstsq(X, moved[keep], rcond=None)
    return start[keep], moved[keep] - X @ coef


def _fit(
    distance: np.ndarray, gamma: np.ndarray, points: int, max_distance: float
) -> Shimmer:
    """The model of the module docstring fitted to the binned semivariogram, each bin
    weighted by its number of pairs."""
    edges = np.arange(0.0, max_distance + BIN_PX, BIN_PX)
    which = np.digitize(distance, edges) - 1
    inside = (which >= 0) & (which < len(edges) - 1)
    counts = np.bincount(which[inside], minlength=len(edges) - 1)
    sums = np.bincount(which[inside], gamma[inside], minlength=len(edges) - 1)
    used = counts > 0
    h = 0.5 * (edges[:-1] + edges[1:])[used]
    g = sums[used] / counts[used]
    weight = np.sqrt(counts[used])

    def model(p: np.ndarray) -> np.ndarray:
        nugget, var, corr = p
        return nugget + var * (1 - np.exp(-(h**2) / (4 * corr**2)))

    sill = float(np.mean(g[-max(1, len(g) // 4) :]))
    start = np.array([max(float(g[0]), 1e-6), max(sill - float(g[0]), 1e-6), max_distance / 8])
    fit = least_squares(
        lambda p: weight * (model(p) - g), start,
        bounds=([0.0, 0.0, 1.0], [np.inf, np.inf, max_distance]),
    )
    nugget, var, corr = fit.x
    rms = math.sqrt(var / 2)
    return Shimmer(
        rms_px=rms,
        corr_px=float(corr) if rms >= MIN_SHIMMER_PX else math.nan,
        tracker_px=math.sqrt(nugget),
        points=points,
    )
