"""Stage 0: sub-pixel point matches between the left image and another view.

Coarse-to-fine, so that it is fast at 16 MP and accurate to a few hundredths of a pixel:

1. SIFT on images shrunk to ~1000 px, ratio test, RANSAC affine: the global map
   (rotation, scale, shift) between the views. Telephoto views of a distant scene
   differ by a near-affine map (the paper's Prop. 1), so this is a good predictor.
2. The other view is warped into the left frame by that affine, and corners of the
   left image are tracked into the warped view with pyramidal Lucas-Kanade at full
   resolution; a forward-backward check rejects unreliable tracks.

The left image's share of both steps (its SIFT features, its corners) is computed once
(:func:`prepare_left`) when it is matched against the right and the back view.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

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
    ``u8``: the same as uint8; ``coarse_scale``: of the copy SIFT ran on, with its
    ``keypoints`` and ``descriptors`` (None: no features); ``corners``: (N, 2) float32,
    full-resolution px, the points tracked into the other view."""

    image: np.ndarray
    u8: np.ndarray
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
    return Reference(left, _to_u8(left), scale, keypoints, descriptors, corners)


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


def brightness_gain(image: np.ndarray, reference: np.ndarray) -> np.ndarray:
    """The smooth gain field that gives ``image`` the local mean brightness (over ~5 %
    of the image side) of ``reference``. Exposure and vignetting differ between frames;
    Lucas-Kanade assumes brightness constancy, and a brightness slope across its window
    biases the shift it finds. Only the mean is matched: equalising local contrast as
    well would follow the texture itself and distort it.
    image, reference: (H, W) float32 grey levels >= 0, aligned; ``image`` is 0 outside
    its footprint, which is left out of the means. Returns (H, W) float32, unitless.
    """
    # The mean over ~5 % of the side is smooth: compute it on a ~256 px copy.
    h, w = image.shape
    k = max(1.0, max(h, w) / 256)
    small = (max(1, round(w / k)), max(1, round(h / k)))
    inside = cv2.threshold(image, 0, 1, cv2.THRESH_BINARY)[1]

    def low_pass(a: np.ndarray) -> np.ndarray:
        a = cv2.resize(a, small, interpolation=cv2.INTER_AREA)
        return cv2.GaussianBlur(a, (0, 0), 0.05 * max(small))

    wgt = low_pass(inside) + 1e-6
    ratio = (low_pass(reference * inside) / wgt) / np.maximum(low_pass(image) / wgt, 1e-3)
    return cv2.resize(ratio.astype(np.float32), (w, h), interpolation=cv2.INTER_LINEAR)


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
        other, A, (left.shape[1], left.shape[0]), flags=cv2.INTER_LINEAR | cv2.WARP_INVERSE_MAP
    )
    # Rounded and saturated to uint8 in the same pass as the gain (as _to_u8 would).
    w8 = cv2.multiply(warped, brightness_gain(warped, left), dtype=cv2.CV_8U)
    l8 = ref.u8
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
