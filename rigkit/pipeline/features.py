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

from dataclasses import dataclass

import cv2
import numpy as np

from rigkit.core.threads import deterministic
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


def _track(a: np.ndarray, b: np.ndarray, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Pyramidal Lucas-Kanade from image ``a`` to ``b``: (new points, status)."""
    crit = (cv2.TERM_CRITERIA_EPS | cv2.TERM_CRITERIA_COUNT, 40, 0.005)
    moved, status, _ = cv2.calcOpticalFlowPyrLK(
        a,
        b,
        points,
        None,
        winSize=(21, 21),
        maxLevel=4,
        criteria=crit,  # type: ignore[call-overload]
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


def prepare_left(
    left: np.ndarray, n_points: int | None = None, settings: PipelineSettings = DEFAULT
) -> Reference:
    """:class:`Reference` of the (H, W) float32 ``left`` image; ``n_points`` overrides
    ``settings.n_points``."""
    scale = min(1.0, settings.coarse_side_px / max(left.shape))
    keypoints, descriptors = _sift(left, scale)
    corners = _corners(left, n_points or settings.n_points).astype(np.float32)
    return Reference(left, local_contrast(left), scale, keypoints, descriptors, corners)


def _coarse_affine(ref: Reference, other: np.ndarray, what: str) -> tuple[np.ndarray, int]:
    scale = ref.coarse_scale
    (k1, d1), (k2, d2) = (ref.keypoints, ref.descriptors), _sift(other, scale)
    if d1 is None or d2 is None or len(k1) < MIN_COARSE_MATCHES or len(k2) < MIN_COARSE_MATCHES:
        found = min(len(k1), len(k2))
        raise PipelineError(f"{what}: only {found} features found (textureless or blank image?)")
    knn = cv2.BFMatcher(cv2.NORM_L2).knnMatch(d1, d2, k=2)
    good = [m[0] for m in knn if len(m) == 2 and m[0].distance < 0.8 * m[1].distance]
    if len(good) < MIN_COARSE_MATCHES:
        raise PipelineError(
            f"{what}: only {len(good)} feature matches (need {MIN_COARSE_MATCHES}); "
            "are these views of the same scene?"
        )
    p1 = np.array([k1[m.queryIdx].pt for m in good], np.float32)
    p2 = np.array([k2[m.trainIdx].pt for m in good], np.float32)
    A, inl = cv2.estimateAffine2D(
        p1, p2, ransacReprojThreshold=2.0, maxIters=4000, confidence=0.999
    )
    n_inl = int(inl.sum()) if inl is not None else 0
    if A is None or n_inl < MIN_COARSE_MATCHES:
        raise PipelineError(
            f"{what}: only {n_inl} of {len(good)} feature matches agree on one alignment; "
            "are these views of the same scene?"
        )
    _check_alignment(A, what)
    # Back to full-resolution pixel coordinates (pixel centres at integers).
    S = np.array([[scale, 0, 0.5 * scale - 0.5], [0, scale, 0.5 * scale - 0.5], [0, 0, 1]])
    A3 = np.linalg.inv(S) @ np.vstack([A, [0, 0, 1]]) @ S
    return A3[:2], n_inl


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


def local_contrast(image: np.ndarray, window: int = CONTRAST_WINDOW_PX) -> np.ndarray:
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
    the means; 128 there). Returns (H, W) uint8.
    """
    h, w = image.shape
    outside = np.isnan(image)
    cut = bool(outside.any())
    values = np.where(outside, np.float32(0), image) if cut else image
    half = (max(1, w // 2), max(1, h // 2))
    box = (window // 2 | 1, window // 2 | 1)

    def local_mean(a: np.ndarray) -> np.ndarray:
        return cv2.boxFilter(cv2.resize(a, half, interpolation=cv2.INTER_AREA), -1, box)

    mean, square = local_mean(values), local_mean(cv2.multiply(values, values))
    if cut:
        seen = np.maximum(local_mean((~outside).astype(np.float32)), np.float32(1e-6))
        mean, square = cv2.divide(mean, seen), cv2.divide(square, seen)
    spread = cv2.sqrt(np.maximum(cv2.subtract(square, cv2.multiply(mean, mean)), np.float32(1e-3)))
    mean, spread = (cv2.resize(a, (w, h), interpolation=cv2.INTER_LINEAR) for a in (mean, spread))
    z = cv2.divide(cv2.subtract(values, mean), spread, scale=32.0)
    out = cv2.add(z, 128.0, dtype=cv2.CV_8U)  # type: ignore[call-overload]  # rounds, saturates
    if cut:
        out[outside] = 128
    return out


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
) -> Matches:
    """:func:`match_views` from a prepared left image, ``ref``."""
    left = ref.image
    A, n_coarse = _coarse_affine(ref, other, what)
    warped = cv2.warpAffine(
        other, A, (left.shape[1], left.shape[0]), flags=cv2.INTER_LINEAR | cv2.WARP_INVERSE_MAP,
        borderMode=cv2.BORDER_CONSTANT, borderValue=float("nan"),
    )
    w8 = local_contrast(warped)
    l8 = ref.contrast
    p0 = ref.corners
    p1, st1 = _track(l8, w8, p0)
    p0b, st2 = _track(w8, l8, p1)  # and back, to check each track
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
