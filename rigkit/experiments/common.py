"""What the baselines share: a rectified pair given by two homographies, dense disparity
on it with rigkit's stereo matcher, and sampling that disparity on the original left grid.

Conventions: pixel centres at integer coordinates; a homography (3, 3) float64 maps
original pixels to rectified ones; disparity is ``x_left - x_right`` on the rectified
canvas, in full-resolution rectified pixels unless said otherwise.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from rigkit.errors import PipelineError
from rigkit.pipeline.rectify import scaling
from rigkit.pipeline.stereo import SGBM, StereoMatcher, restrict_to_footprints

DISPARITY_MARGIN = 24  # px added on both sides of the matched disparity range
STEREO_SCALE = 0.5  # stereo at half resolution, as rigkit does


@dataclass(frozen=True)
class RectifiedPair:
    """Two rectifying homographies onto one ``size`` = (w, h) canvas (px) and the
    disparity range (lo, hi) (px, full resolution) the matches span, with a margin.
    ``shift`` (px) was added to the right image's x, so that a disparity ``d`` on the
    canvas is ``d + shift`` between the homographies before the canvas."""

    H_left: np.ndarray
    H_right: np.ndarray
    size: tuple[int, int]
    disparity_range: tuple[int, int]
    shift: float


def apply_h(H: np.ndarray, pts: np.ndarray) -> np.ndarray:
    """(N, 2) pixels through a (3, 3) homography -> (N, 2) pixels."""
    q = pts @ H[:, :2].T + H[:, 2]
    return q[:, :2] / q[:, 2:3]


def on_canvas(
    H_left: np.ndarray,
    H_right: np.ndarray,
    image_size: tuple[int, int],
    pts_left: np.ndarray,
    pts_right: np.ndarray,
) -> RectifiedPair:
    """Put two rectifying homographies on a canvas holding the left image's footprint,
    with the right image shifted so that the matches' median disparity is 0.

    image_size: (w, h) of the originals; pts_left/pts_right: (N, 2) matched pixels.
    Raises PipelineError when the warp is degenerate (canvas over 4x the image).
    """
    w, h = image_size
    corners = np.array([[0, 0], [w - 1, 0], [0, h - 1], [w - 1, h - 1]], float)
    wc = apply_h(H_left, corners)
    lo = np.floor(wc.min(axis=0))
    size = (int(np.ceil(wc[:, 0].max() - lo[0])) + 1, int(np.ceil(wc[:, 1].max() - lo[1])) + 1)
    if not np.all(np.isfinite(wc)) or size[0] * size[1] > 4 * w * h:
        raise PipelineError(f"rectification is degenerate (canvas {size[0]}x{size[1]} px)")
    T = np.array([[1, 0, -lo[0]], [0, 1, -lo[1]], [0, 0, 1.0]])
    d = apply_h(H_left, pts_left)[:, 0] - apply_h(H_right, pts_right)[:, 0]
    shift = float(np.round(np.median(d)))
    d_lo, d_hi = np.percentile(d - shift, [0.5, 99.5])
    rng = (int(np.floor(d_lo)) - DISPARITY_MARGIN, int(np.ceil(d_hi)) + DISPARITY_MARGIN)
    S = np.array([[1, 0, shift], [0, 1, 0], [0, 0, 1.0]])
    return RectifiedPair(T @ H_left, T @ S @ H_right, size, rng, shift)


def dense_disparity(
    left: np.ndarray,
    right: np.ndarray,
    pair: RectifiedPair,
    matcher: StereoMatcher | None = None,
    scale: float = STEREO_SCALE,
) -> np.ndarray:
    """Disparity of the rectified pair at ``scale`` x the canvas size.

    left, right: (H, W) float32 grey originals. Returns (h, w) float32 in px of the
    full-resolution canvas, ``x_left - x_right``, NaN where unknown or where either
    pixel falls outside its image's footprint.
    """
    matcher = matcher or SGBM()
    size = (round(pair.size[0] * scale), round(pair.size[1] * scale))
    warped, masks = [], []
    ones = np.full(left.shape, 255, np.uint8)
    S = scaling(scale)
    small = (round(left.shape[1] * scale), round(left.shape[0] * scale))
    for img, H in ((left, pair.H_left), (right, pair.H_right)):
        # Area-average first so that the warp does not alias, then one bilinear warp.
        img_s = cv2.resize(img, small, interpolation=cv2.INTER_AREA)
        warped.append(cv2.warpPerspective(img_s, S @ H @ np.linalg.inv(S), size))
        m = cv2.warpPerspective(ones, S @ H, size, flags=cv2.INTER_NEAREST)
        masks.append(cv2.erode(m, np.ones((3, 3), np.uint8)) > 0)
    lo, hi = pair.disparity_range
    disp = matcher(warped[0], warped[1], (int(np.floor(lo * scale)), int(np.ceil(hi * scale))))
    return restrict_to_footprints(disp, masks[0], masks[1]) / np.float32(scale)


def sample_disparity(
    disparity: np.ndarray, H_left: np.ndarray, pts: np.ndarray, scale: float = STEREO_SCALE
) -> tuple[np.ndarray, np.ndarray]:
    """At original left pixels ``pts`` (N, 2): their rectified positions (N, 2, px) and
    the disparity there (N,), bilinear, NaN off the map or next to a hole."""
    xr = apply_h(H_left, pts)
    xs = apply_h(scaling(scale), xr).astype(np.float32).reshape(-1, 1, 2)
    d = cv2.remap(disparity, xs[..., 0], xs[..., 1], cv2.INTER_LINEAR, borderValue=np.nan)
    return xr, d.ravel()


def left_grid(
    disparity: np.ndarray, H_left: np.ndarray, shape: tuple[int, int], scale: float = STEREO_SCALE
) -> tuple[np.ndarray, np.ndarray]:
    """For every pixel of the (H, W) original left image: its rectified position
    (H, W, 2) float64 px and the disparity there (H, W) float32 (NaN = none)."""
    h, w = shape
    v, u = np.mgrid[0:h, 0:w].astype(np.float64)
    xr = apply_h(H_left, np.stack([u.ravel(), v.ravel()], axis=1))
    xs = apply_h(scaling(scale), xr).astype(np.float32)
    d = cv2.remap(
        disparity, xs[:, 0].reshape(h, w), xs[:, 1].reshape(h, w), cv2.INTER_LINEAR,
        borderValue=np.nan,
    )
    return xr.reshape(h, w, 2), d
