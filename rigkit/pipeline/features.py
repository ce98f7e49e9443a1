"""Stage 0: sub-pixel point matches between the left image and another view.

Coarse-to-fine, so that it is fast at 16 MP and accurate to a few hundredths of a pixel:

1. SIFT on images shrunk to ~1000 px, ratio test, RANSAC affine: the global map
   (rotation, scale, shift) between the views. Telephoto views of a distant scene
   differ by a near-affine map (the paper's Prop. 1), so this is a good predictor.
2. The other view is warped into the left frame by that affine, both views are
   normalised to their local contrast (:func:`local_contrast`), and corners of the
   left image are tracked into the warped view with pyramidal Lucas-Kanade at full
   resolution; a forward-backward check rejects unreliable tracks.

The left image's share of both steps (its SIFT features, its corners) is computed once
(:func:`prepare_left`) when it is matched against the right and the back view.
"""

from __future__ import annotations

from collections.abc import Sequence
from contextlib import nullcontext
from dataclasses import dataclass

import cv2
import numpy as np

from rigkit.core.threads import ViewPool, deterministic
from rigkit.errors import PipelineError
from rigkit.pipeline.settings import PipelineSettings

MIN_COARSE_MATCHES = 12
DEFAULT = PipelineSettings()


@dataclass(frozen=True)
class Matches:
    """Point correspondences: ``left[i]`` (px, original left image) <-> ``other[i]``
    (px, original other image), both (N, 2) float64 as (u, v). ``affine`` (2, 3) maps
    left pixels to the other view to first order."""

    left: np.ndarray
    other: np.ndarray
    affine: np.ndarray
    coarse_inliers: int


def _track(a: np.ndarray, b: np.ndarray, points: np.ndarray,
           start: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Pyramidal Lucas-Kanade from image ``a`` to ``b``: (new points, status), each
    search starting at ``start`` (N, 2) float32 (None: where the point is in ``a``)."""
    crit = (cv2.TERM_CRITERIA_EPS | cv2.TERM_CRITERIA_COUNT, 40, 0.005)
    initial = points.copy() if start is None else start.copy()
    moved, status, _ = cv2.calcOpticalFlowPyrLK(
        a,
        b,
        points,
        initial,
        winSize=(21, 21),
        maxLevel=4,
        criteria=crit,
        flags=0 if start is None else cv2.OPTFLOW_USE_INITIAL_FLOW,
    )
    return moved, status


def _to_u8(img: np.ndarray) -> np.ndarray:
    return np.clip(np.rint(img), 0, 255).astype(np.uint8)


@dataclass(frozen=True)
class Reference:
    """The left image, prepared once for matching it against each other view (its SIFT
    features and corners do not depend on the other view). ``image``: (H, W) float32;
    ``contrast``: its :func:`local_contrast`, which is what is tracked; ``coarse_scale``:
    of the copy SIFT ran on, with its ``keypoints`` and ``descriptors`` (None: no
    features); ``corners``: (N, 2) float32, full-resolution px, the points tracked into
    the other view."""

    image: np.ndarray
    contrast: np.ndarray
    coarse_scale: float
    keypoints: tuple
    descriptors: np.ndarray | None
    corners: np.ndarray


SIFT_CONTRAST = 0.01
"""SIFT's contrast threshold (OpenCV's default is 0.04). Fine, low-contrast texture
(hazy ground at 1/4.5 of full resolution) gives few features at the default: on a
scene with two plain buildings, 276 left features and 26 agreeing matches, which
agreed on a half turn of the view; at 0.01, 3206 features and 450 agreeing matches on
the true alignment, for the same time."""


def _sift(image: np.ndarray, scale: float) -> tuple[tuple, np.ndarray | None]:
    size = (round(image.shape[1] * scale), round(image.shape[0] * scale))
    small = _to_u8(cv2.resize(image, size, interpolation=cv2.INTER_AREA))
    sift = cv2.SIFT_create(nfeatures=4000, contrastThreshold=SIFT_CONTRAST)  # type: ignore[attr-defined]
    return sift.detectAndCompute(small, None)


def coarse_scale(shape: tuple[int, ...], settings: PipelineSettings = DEFAULT) -> float:
    """Of the copies SIFT runs on, for images of ``shape`` (H, W)."""
    return min(1.0, settings.coarse_side_px / max(shape))


def prepare_left(
    left: np.ndarray, n_points: int | None = None, settings: PipelineSettings = DEFAULT,
    pool: ViewPool | None = None,
) -> Reference:
    """:class:`Reference` of the (H, W) float32 ``left`` image; ``n_points`` overrides
    ``settings.n_points``. Its three parts (SIFT, corners, contrast) are found in
    ``pool``'s threads where given."""
    scale = coarse_scale(left.shape, settings)
    with ViewPool(1) if pool is None else nullcontext(pool) as run:
        sift = run.submit(_sift, left, scale)
        corners = run.submit(_corners, left, n_points or settings.n_points)
        contrast = run.submit(local_contrast, left)
        keypoints, descriptors = sift.result()
        return Reference(left, contrast.result(), scale, keypoints, descriptors,
                         corners.result().astype(np.float32))


def _coarse_affine(ref: Reference, other: np.ndarray, what: str,
                   other_features: tuple[tuple, np.ndarray | None] | None = None
                   ) -> tuple[np.ndarray, int, tuple[np.ndarray, np.ndarray]]:
    """The (2, 3) affine map from the left view's pixels to ``other``'s, from SIFT on
    the coarse copies, how many feature matches agree on it, and every feature match
    that passed the ratio test (left, other: (M, 2) float64, full-resolution px) for
    :func:`_predicted`. ``other_features``: ``other``'s SIFT keypoints and descriptors
    at ``ref.coarse_scale`` where they are already known (None: found here)."""
    scale = ref.coarse_scale
    (k1, d1), (k2, d2) = (ref.keypoints, ref.descriptors), other_features or _sift(other, scale)
    if d1 is None or d2 is None or len(k1) < MIN_COARSE_MATCHES or len(k2) < MIN_COARSE_MATCHES:
        found = min(len(k1), len(k2))
        raise PipelineError(f"{what}: only {found} features found (textureless or blank image?)")
    query, train = _ratio_matches(d1, d2)
    if len(query) < MIN_COARSE_MATCHES:
        raise PipelineError(
            f"{what}: only {len(query)} feature matches (need {MIN_COARSE_MATCHES}); "
            "are these views of the same scene?"
        )
    p1 = np.array([k1[i].pt for i in query], np.float32)
    p2 = np.array([k2[i].pt for i in train], np.float32)
    A, inl = cv2.estimateAffine2D(
        p1, p2, ransacReprojThreshold=2.0, maxIters=4000, confidence=0.999
    )
    n_inl = int(inl.sum()) if inl is not None else 0
    if A is None or n_inl < MIN_COARSE_MATCHES:
        raise PipelineError(
            f"{what}: only {n_inl} of {len(query)} feature matches agree on one alignment; "
            "are these views of the same scene?"
        )
    _check_alignment(A, what)
    # Back to full-resolution pixel coordinates (pixel centres at integers).
    S = np.array([[scale, 0, 0.5 * scale - 0.5], [0, scale, 0.5 * scale - 0.5], [0, 0, 1]])
    A3 = np.linalg.inv(S) @ np.vstack([A, [0, 0, 1]]) @ S
    full = [(p.astype(np.float64) + 0.5) / scale - 0.5 for p in (p1, p2)]
    return A3[:2], n_inl, (full[0], full[1])


FLOW_GRID = 8
"""Cells per image side of the feature matches' residual field (:func:`_predicted`)."""
FLOW_MIN_MATCHES = 5
"""Feature matches a cell needs for its median residual to count."""
FLOW_MAX = 0.1
"""The largest residual a cell may take, as a fraction of the image width: depth from 200
to 450 m parallaxes by 5 % of the width at 6 deg and 2 m; a larger median is a cell of
false matches (where the other view does not see the scene at all)."""
FLOW_MIN_PX = 4.0
"""Residuals of the affine map smaller than this (full-resolution px) are left to the
tracker's pyramid: a search starts where the affine map puts a corner, as it always
did (a scene at one depth gives residuals of a pixel or two: its matches are those of
an affine prediction, bit for bit)."""


def _predicted(corners: np.ndarray, left: np.ndarray, other: np.ndarray, A: np.ndarray,
               shape: tuple[int, int]) -> np.ndarray | None:
    """Where to start each corner's search in the affine-warped view: (N, 2) float32,
    or None where the affine map predicts every part of the view.

    One affine map predicts a view only where the scene lies at about one depth:
    ground receding from 200 to 450 m shifts its near part in the right view by tens
    of px more than the map fitted to the rest (-90 px at the bottom of one 4608 px
    frame), beyond what the tracker finds from the map's prediction, and no corner
    there was tracked. The feature matches (``left``, ``other``: (M, 2) px, full
    resolution, outliers among them) say where: their residuals against ``A``, the
    median per cell of a :data:`FLOW_GRID` grid, where at least half its matches (and
    :data:`FLOW_MIN_MATCHES`) agree with it and it is under :data:`FLOW_MAX` of the
    width (cells without take their nearest cell's),
    interpolated to the corners; a corner starts there where that residual exceeds
    :data:`FLOW_MIN_PX`. The tracker's forward-backward check judges each track as
    before."""
    h, w = shape
    Ainv = cv2.invertAffineTransform(A)
    residual = other @ Ainv[:, :2].T + Ainv[:, 2] - left  # in the warped view's frame
    cell = np.floor(left / [w / FLOW_GRID, h / FLOW_GRID]).astype(int).clip(0, FLOW_GRID - 1)
    label = cell[:, 1] * FLOW_GRID + cell[:, 0]
    field = np.full((FLOW_GRID * FLOW_GRID, 2), np.nan)
    for k in np.unique(label):
        here = residual[label == k]
        if len(here) < FLOW_MIN_MATCHES:
            continue
        median = np.median(here, axis=0)
        agree = np.hypot(*(here - median).T) <= max(FLOW_MIN_PX, 0.2 * np.hypot(*median))
        plausible = np.hypot(*median) <= FLOW_MAX * w
        if plausible and agree.sum() >= max(FLOW_MIN_MATCHES, len(here) // 2):
            field[k] = np.median(here[agree], axis=0)
    known = np.isfinite(field[:, 0])
    if not known.any():
        return None
    centres = np.stack(np.meshgrid(np.arange(FLOW_GRID), np.arange(FLOW_GRID)), -1).reshape(-1, 2)
    for k in np.flatnonzero(~known):  # the nearest cell that has one
        field[k] = field[known][np.argmin(np.sum((centres[known] - centres[k]) ** 2, axis=1))]
    grid = field.reshape(FLOW_GRID, FLOW_GRID, 2).astype(np.float32)
    # bilinear between cell centres: cell k's centre at (k + 0.5) * size - 0.5 in px
    gx = corners[:, 0] / (w / FLOW_GRID) - 0.5
    gy = corners[:, 1] / (h / FLOW_GRID) - 0.5
    at = (gx.astype(np.float32).reshape(-1, 1), gy.astype(np.float32).reshape(-1, 1))
    flow = cv2.remap(grid, *at, cv2.INTER_LINEAR,
                     borderMode=cv2.BORDER_REPLICATE).reshape(-1, 2)
    far = np.hypot(flow[:, 0], flow[:, 1]) > FLOW_MIN_PX
    if not far.any():
        return None
    return np.where(far[:, None], corners + flow, corners).astype(np.float32)


RATIO = 0.8
"""Lowe's ratio test: a feature's nearest descriptor must be nearer than this times its
second nearest."""
_ROWS = 1024  # query descriptors per block of the distance matrix (16 MB at 4000 features)


def _ratio_matches(d1: np.ndarray, d2: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The feature matches that pass the ratio test, nearest descriptor first: (query
    indices into ``d1``, train indices into ``d2``), each (M,) int, in query order.

    The same matches as OpenCV's brute-force ``knnMatch(d1, d2, k=2)`` with the test on
    its ``DMatch.distance`` values, at a fraction of its time (0.4 s for two sets of
    4000 at 16 MP): SIFT's descriptors (N, 128) float32 hold whole numbers (OpenCV
    rounds them to bytes, and normalises them to a length of 512), so the squared
    distances, taken as ``|a|^2 + |b|^2 - 2 a.b`` in float32 by one matrix product, are
    whole numbers below 2^24, exact, and their float32 square roots are OpenCV's
    distances bit for bit. Descriptors that are not such (another extractor) go to
    OpenCV's matcher."""
    exact = (np.array_equal(d1, np.rint(d1)) and np.array_equal(d2, np.rint(d2))
             and max(float(np.square(d1, dtype=np.float64).sum(1).max()),
                     float(np.square(d2, dtype=np.float64).sum(1).max())) < 2.0**22)
    if not exact:
        knn = cv2.BFMatcher(cv2.NORM_L2).knnMatch(d1, d2, k=2)
        pairs = [m[0] for m in knn if len(m) == 2 and m[0].distance < RATIO * m[1].distance]
        return (np.array([m.queryIdx for m in pairs], int),
                np.array([m.trainIdx for m in pairs], int))
    a, b = np.asarray(d1, np.float32), np.asarray(d2, np.float32)
    b_sq = np.einsum("ij,ij->i", b, b)
    nearest = np.empty(len(a), np.intp)
    d_first, d_second = np.empty(len(a), np.float32), np.empty(len(a), np.float32)
    for r0 in range(0, len(a), _ROWS):
        block = a[r0 : r0 + _ROWS]
        sq = block @ (np.float32(-2) * b).T  # -2 a.b, exact: whole numbers below 2^24
        sq += b_sq
        sq += np.einsum("ij,ij->i", block, block)[:, None]
        rows = np.arange(len(block))
        best = np.argmin(sq, axis=1)
        nearest[r0 : r0 + len(block)] = best
        d_first[r0 : r0 + len(block)] = sq[rows, best]
        sq[rows, best] = np.inf
        d_second[r0 : r0 + len(block)] = sq.min(axis=1)
    first = np.sqrt(np.maximum(d_first, 0)).astype(np.float64)
    second = np.sqrt(np.maximum(d_second, 0)).astype(np.float64)
    good = np.flatnonzero(first < RATIO * second)
    return good, nearest[good]


MAX_TURN_DEG = 45.0  # a rig's views are turned by a few degrees about the axis at most


def _check_alignment(A: np.ndarray, what: str) -> None:
    """PipelineError where the (2, 3) affine map found between two views is no
    alignment of two views of one rig: mirrored, turned by more than MAX_TURN_DEG, or
    scaled by more than 2x (repeated structure, such as a facade's windows, can agree
    on one)."""
    det = float(np.linalg.det(A[:, :2]))
    turn = float(np.degrees(np.arctan2(A[1, 0] - A[0, 1], A[0, 0] + A[1, 1])))
    if det <= 0 or abs(turn) > MAX_TURN_DEG or not 0.25 < det < 4:
        raise PipelineError(
            f"{what}: the features agree only on an alignment turned by {turn:.0f} deg "
            f"and scaled by {np.sqrt(abs(det)):.2f}x, which no rig gives; are these views "
            "of the same scene, with enough texture?"
        )


def _corners(left: np.ndarray, n_points: int) -> np.ndarray:
    """Well-spread corners of the left image, (N, 2) float32, full-resolution px."""
    half = cv2.resize(left, (left.shape[1] // 2, left.shape[0] // 2), interpolation=cv2.INTER_AREA)
    min_dist = max(4.0, 0.7 * np.sqrt(half.size / n_points))
    pts = cv2.goodFeaturesToTrack(half, n_points, 0.005, min_dist, blockSize=5)
    if pts is None:
        return np.empty((0, 2), np.float32)
    return pts.reshape(-1, 2) * 2 + 0.5


CONTRAST_WINDOW_PX = 31
"""Side (px) of the window :func:`local_contrast` takes a pixel's mean and spread over:
wider than Lucas-Kanade's 21 px window, so that within a tracked window the scaling
changes little and the texture keeps its shape."""


def local_contrast(
    image: np.ndarray, window: int = CONTRAST_WINDOW_PX, overwrite: bool = False
) -> np.ndarray:
    """The image as Lucas-Kanade tracks it: each pixel's difference from the mean of the
    ``window`` around it, in units of their standard deviation, as uint8 (128 + 32 z,
    saturated at 4 standard deviations).

    Texture under haze, a few grey levels deep, loses most of its detail when rounded
    to uint8 as it is, and the tracker's forward-backward check then drops it; views
    taken minutes apart also differ in contrast, not only in mean (a drifting cloud
    shadow dims the sunlit part of a patch but not the haze in front of it). Matching
    the mean alone (a smooth gain), 670 of a town scene's 1768 left corners were
    tracked into the back view within 0.1 px forward-backward; normalised, 1157, with
    the common tracks no less accurate against the truth (docs/results-log.md). The same
    filter on both views keeps the shift between them: it is the normalisation of
    zero-mean normalised cross-correlation, applied before the tracker. The mean and
    spread vary at the window's scale, so they are taken on a half-size copy.

    image: (H, W) float32 grey levels, NaN outside the view's footprint (left out of
    the means; 128 there); ``overwrite``: it may be changed (NaN set to 0), which
    spares a copy. Returns (H, W) uint8.

    Computed in strips of ``_STRIP_ROWS`` rows, so that no full-size float image but
    ``image`` itself is made and each strip's steps run in the cache: the halving
    averages 2x2 blocks, which strips of an even number of rows share with the whole,
    and the doubling is given one more row of the half-size copy each side of a strip,
    so every pixel comes out as from the whole image, bit for bit. Images with an odd
    side are taken whole.
    """
    h, w = image.shape
    outside = np.isnan(image)
    cut = bool(outside.any())
    values = image
    if cut:
        values = image if overwrite else image.copy()
        cv2.patchNaNs(values, 0)
    half = (max(1, w // 2), max(1, h // 2))
    step = _STRIP_ROWS if h % 2 == 0 and w % 2 == 0 else h
    parts = 3 if cut else 2  # the values, their squares, and where they are seen
    halves = [np.empty((half[1], half[0]), np.float32) for _ in range(parts)]
    for r0 in range(0, h, step):
        rows = slice(r0, min(r0 + step, h))
        size = (half[0], half[1] if step == h else (rows.stop - r0) // 2)
        shrunk = slice(r0 // 2, r0 // 2 + size[1])
        v = values[rows]
        strip = [v, cv2.multiply(v, v)]
        if cut:
            strip.append(np.logical_not(outside[rows]).astype(np.float32))
        for out, a in zip(halves, strip, strict=True):
            out[shrunk] = cv2.resize(a, size, interpolation=cv2.INTER_AREA)
    box = (window // 2 | 1, window // 2 | 1)
    mean, square = (cv2.boxFilter(a, -1, box) for a in halves[:2])
    if cut:
        seen = np.maximum(cv2.boxFilter(halves[2], -1, box), np.float32(1e-6))
        mean, square = cv2.divide(mean, seen), cv2.divide(square, seen)
    spread = cv2.sqrt(np.maximum(cv2.subtract(square, cv2.multiply(mean, mean)), np.float32(1e-3)))
    out = np.empty((h, w), np.uint8)
    for r0 in range(0, h, step):
        r1 = min(r0 + step, h)
        if step == h:
            s0, s1, first = 0, half[1], 0
            size = (w, h)
        else:  # the half-size rows this strip's doubling reads, one more each side
            s0, s1 = max(r0 // 2 - 1, 0), min(r1 // 2 + 1, half[1])
            first, size = r0 - 2 * s0, (w, 2 * (s1 - s0))
        m, sd = (cv2.resize(a[s0:s1], size, interpolation=cv2.INTER_LINEAR)[first:first + r1 - r0]
                 for a in (mean, spread))
        z = cv2.subtract(values[r0:r1], m)
        cv2.divide(z, sd, dst=z, scale=32.0)
        cv2.add(z, 128.0, dst=out[r0:r1], dtype=cv2.CV_8U)  # type: ignore[call-overload]  # rounds, saturates
        if cut:
            np.copyto(out[r0:r1], 128, where=outside[r0:r1])  # 4x a boolean index
    return out


_STRIP_ROWS = 32
"""Rows of :func:`local_contrast`'s strips (even)."""


@deterministic
def match_views(
    left: np.ndarray,
    other: np.ndarray,
    what: str = "left/other",
    n_points: int | None = None,
    settings: PipelineSettings = DEFAULT,
) -> Matches:
    """Sub-pixel matches from ``left`` to ``other`` ((H, W) float32 grey images).

    ``what`` names the pair in error messages; ``n_points`` overrides
    ``settings.n_points``. Raises PipelineError when the views do not match
    (textureless, unrelated, or too few reliable tracks). To match one left image
    against several views, :func:`prepare_left` it once and call :func:`match_to`.
    """
    return match_to(prepare_left(left, n_points, settings), other, what, settings)


def match_to(
    ref: Reference, other: np.ndarray, what: str = "left/other",
    settings: PipelineSettings = DEFAULT,
    other_features: tuple[tuple, np.ndarray | None] | None = None,
) -> Matches:
    """:func:`match_views` from a prepared left image, ``ref``; ``other_features``:
    ``other``'s SIFT features at ``ref.coarse_scale`` where already found."""
    left = ref.image
    A, n_coarse, features = _coarse_affine(ref, other, what, other_features)
    warped = cv2.warpAffine(
        other, A, (left.shape[1], left.shape[0]), flags=cv2.INTER_LINEAR | cv2.WARP_INVERSE_MAP,
        borderMode=cv2.BORDER_CONSTANT, borderValue=float("nan"),
    )
    w8 = local_contrast(warped, overwrite=True)
    del warped
    l8 = ref.contrast
    p0 = ref.corners
    start = _predicted(p0, *features, A, left.shape)
    p1, st1 = _track(l8, w8, p0, start)
    p0b, st2 = _track(w8, l8, p1, None if start is None else p0)  # and back, to check each
    h, w = left.shape
    fb = np.linalg.norm(p0b - p0, axis=1)
    ok = (st1[:, 0] == 1) & (st2[:, 0] == 1) & (fb < settings.fb_max_px)
    ok &= (p1[:, 0] > 10) & (p1[:, 0] < w - 11) & (p1[:, 1] > 10) & (p1[:, 1] < h - 11)
    if ok.sum() < 50:
        raise PipelineError(f"{what}: only {int(ok.sum())} reliable sub-pixel matches (need 50)")
    pl = p0[ok].astype(np.float64)
    pw = p1[ok].astype(np.float64)
    po = pw @ A[:, :2].T + A[:, 2]
    return Matches(left=pl, other=po, affine=A, coarse_inliers=n_coarse)


def match_all(
    left: np.ndarray, others: Sequence[tuple[np.ndarray, str]],
    settings: PipelineSettings = DEFAULT, n_points: int | None = None,
) -> list[Matches]:
    """:func:`match_views` of ``left`` against each of ``others`` ((image, what) pairs;
    (H, W) float32 grey images), the left image prepared once, and the views' work
    spread over a :class:`rigkit.core.threads.ViewPool`: SIFT on every view and the
    left view's corners and contrast at once, then each view's alignment and tracking.
    Each view's matches are those :func:`match_to` finds alone, whatever the number of
    threads; the first view's error (in the order given) is raised."""
    scale = coarse_scale(left.shape, settings)
    with ViewPool() as pool:
        features = [pool.submit(_sift, other, scale) for other, _ in others]
        ref = prepare_left(left, n_points, settings, pool)
        found = [pool.submit(match_to, ref, other, what, settings, f.result())
                 for (other, what), f in zip(others, features, strict=True)]
        return [f.result() for f in found]
