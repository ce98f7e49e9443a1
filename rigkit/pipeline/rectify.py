"""Stage 1: pseudo-rectification of the left/right pair.

The paper (sec. 4, Alg. 2) fits two affine warps so that matches share a row. Since the
focal length is known, we model the warps exactly as rotations, ``H = K R K^-1``
(the affine map is only their first-order approximation, ~2 px off at the edges of a
16 MP frame for a 1 deg tilt), and fit the rotations by robust least squares:

* ``R_lr``: orientation of the right camera in the left frame (3 angles);
* ``R_rect``: rotation of the rectified frame about the left optical axis, i.e. the
  direction of the baseline in the left image (1 angle). It is seen only through the
  parallax (the row error grows with disparity), so it gets a weak prior towards 0
  and cannot run away when the scene is nearly flat - the near-degeneracy that makes
  the paper's 5-unknown linear RANSAC unstable.

Rectified rows agree to a few hundredths of a pixel. What stays unknown is the right
camera's yaw, which shifts every disparity by almost the same amount: the global
offset of the paper, fixed by the back camera in :mod:`rigkit.pipeline.ambiguity`.
The principal point is taken at the image centre; its error is absorbed by the
rotations.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from rigkit.core.lazy import function
from rigkit.errors import PipelineError
from rigkit.geometry import intrinsics, rot_z, rotvec_to_matrix
from rigkit.pipeline.features import Matches
from rigkit.pipeline.lens import Lens, smooth_map
from rigkit.pipeline.settings import PipelineSettings

least_squares = function("scipy.optimize", "least_squares")

ROLL_PRIOR_RAD = np.radians(2.0)
DEFAULT = PipelineSettings()


@dataclass(frozen=True)
class Rectification:
    """Rectifying warps of the left/right pair (full-resolution pixels).

    ``H_left``/``H_right`` (3, 3) map original pixels to rectified ones, both onto a
    ``size`` = (w, h) canvas. In rectified images a scene point has the same row and
    ``x_left - x_right = d_rect``, with ``d_rect`` in ``disparity_range`` (px). ``K`` is
    the assumed intrinsics (f, image-centre principal point); ``R_rect`` (left camera ->
    rectified frame) and ``R_lr`` (right camera -> left camera) are the fitted rotations;
    ``shift`` (px) is the horizontal translation applied to the right image after its
    rotation; ``canvas`` (3, 3) the translation applied to both; ``row_stretch_sq``
    (unitless, squared) how much the right view's rows still stretch against the left
    one's from top to bottom (the slope of the matches' row residuals down the image),
    beyond what the matches' scatter explains: rotations cannot absorb it, and heat
    shimmer at the scale of the frame leaves it (:func:`row_stretch_sq`).
    """

    H_left: np.ndarray
    H_right: np.ndarray
    size: tuple[int, int]
    disparity_range: tuple[int, int]
    K: np.ndarray
    R_rect: np.ndarray
    R_lr: np.ndarray
    shift: float
    canvas: np.ndarray
    row_rms_px: float
    inliers: int
    row_stretch_sq: float = 0.0


def _homographies(p: np.ndarray, K: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    R_rect = rot_z(p[0])
    R_lr = rotvec_to_matrix(p[1:4])
    Ki = np.linalg.inv(K)
    return K @ R_rect @ Ki, K @ R_rect @ R_lr @ Ki, R_lr


def apply_homography(H: np.ndarray, pts: np.ndarray) -> np.ndarray:
    """Map (N, 2) pixel coordinates through a 3x3 homography."""
    q = pts @ H[:, :2].T + H[:, 2]
    return q[:, :2] / q[:, 2:3]


def _row_residuals(p: np.ndarray, K: np.ndarray, pl: np.ndarray, pr: np.ndarray) -> np.ndarray:
    Hl, Hr, _ = _homographies(p, K)
    res = apply_homography(Hl, pl)[:, 1] - apply_homography(Hr, pr)[:, 1]
    return np.append(res, 0.05 * p[0] / ROLL_PRIOR_RAD)


def _initial_params(m: Matches, f: float) -> np.ndarray:
    """Right-camera rotation vector from the coarse affine (small angles).

    Image content turned by +a (x towards y) means a camera turned by -a about z; a
    shift (du, dv) means a turn of (+dv/f, -du/f) about x and y (x right, y down)."""
    A = m.affine
    content_turn = np.arctan2(A[1, 0] - A[0, 1], A[0, 0] + A[1, 1])
    centre = m.left.mean(axis=0)
    du, dv = A[:, :2] @ centre + A[:, 2] - centre
    return np.array([0.0, np.arctan(dv / f), -np.arctan(du / f), -content_turn])


def pseudo_rectify(
    matches: Matches,
    f: float,
    image_size: tuple[int, int],
    settings: PipelineSettings = DEFAULT,
    lens: Lens | None = None,
) -> Rectification:
    """Fit rectifying rotations to left/right ``matches`` (ideal pinhole pixels, see
    :mod:`rigkit.pipeline.lens`) for focal length ``f`` (px) and original image
    ``image_size`` (w, h); the canvas holds the left image as its ``lens`` (None: a
    pinhole) puts it in ideal pixels."""
    w, h = image_size
    K = intrinsics(f, (w - 1) / 2, (h - 1) / 2)
    pl, pr = matches.left, matches.other
    p0 = _initial_params(matches, f)
    # A plain least-squares pass brings the big tilts in, a robust pass settles on inliers.
    fit = least_squares(_row_residuals, p0, args=(K, pl, pr), x_scale=1e-3)
    fit = least_squares(
        _row_residuals, fit.x, args=(K, pl, pr), loss="soft_l1", f_scale=0.3, x_scale=1e-3
    )
    res = _row_residuals(fit.x, K, pl, pr)[:-1]
    inl = np.abs(res) < 1.0
    if inl.sum() < 30:
        raise PipelineError(
            f"left/right: only {int(inl.sum())} of {len(res)} matches can share a row after "
            "rectification; are these the left and right views of one rig?"
        )
    fit = least_squares(_row_residuals, fit.x, args=(K, pl[inl], pr[inl]), x_scale=1e-3)
    Hl, Hr, R_lr = _homographies(fit.x, K)
    rows = _row_residuals(fit.x, K, pl[inl], pr[inl])[:-1]
    rms = float(np.sqrt(np.mean(rows**2)))

    # Canvas: the left image's rectified footprint; right image shifted to small disparities.
    # Its origin is whole pixels from the recorded left grid, as with the image centre as
    # principal point: the fraction of a fitted one's shift would resample the left image
    # at another phase, and the texture test measures the noise after that resampling
    # (stereo.surface_mask; on one 4608 px scene at the stereo scale: 2.0 grey levels at
    # half a pixel's phase, 3.7 at none, and 20x the pixels without surface).
    corners = np.array([[0, 0], [w - 1, 0], [0, h - 1], [w - 1, h - 1]], float)
    centre = np.zeros(2) if lens is None else np.array(lens.shift)
    if lens is not None:
        corners = lens.to_ideal(corners)
    wc = apply_homography(Hl, corners)
    lo = np.floor(wc.min(axis=0) + centre) - centre
    size = (int(np.ceil(wc[:, 0].max() - lo[0])) + 1, int(np.ceil(wc[:, 1].max() - lo[1])) + 1)
    canvas = np.array([[1, 0, -lo[0]], [0, 1, -lo[1]], [0, 0, 1.0]])
    d = apply_homography(Hl, pl[inl])[:, 0] - apply_homography(Hr, pr[inl])[:, 0]
    shift = float(np.round(np.median(d)))
    d_lo, d_hi = np.percentile(d - shift, [0.5, 99.5])
    margin = settings.disparity_margin_px
    rng = (int(np.floor(d_lo)) - margin, int(np.ceil(d_hi)) + margin)
    T = np.array([[1, 0, shift], [0, 1, 0], [0, 0, 1.0]])
    return Rectification(
        H_left=canvas @ Hl,
        H_right=canvas @ T @ Hr,
        size=size,
        disparity_range=rng,
        K=K,
        R_rect=rot_z(fit.x[0]),
        R_lr=R_lr,
        shift=shift,
        canvas=canvas,
        row_rms_px=rms,
        inliers=int(inl.sum()),
        row_stretch_sq=row_stretch_sq(pl[inl], rows),
    )


def row_stretch_sq(left_px: np.ndarray, rows: np.ndarray) -> float:
    """The squared slope, down the image, of the row residuals ``rows`` (N,) px of
    rectified matches at left pixels ``left_px`` (N, 2), less the part the residuals'
    scatter gives it (0 where that is all): a plane fitted by least squares."""
    try:
        slope, variance = plane_slopes(left_px, rows)
    except np.linalg.LinAlgError:
        return 0.0
    return max(float(slope[1]) ** 2 - float(variance[1]), 0.0)


def plane_slopes(px: np.ndarray, values: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """A plane fitted by least squares to ``values`` (N,) or (N, k) at pixels ``px``
    (N, 2): its slopes along x and y, (2,) or (2, k) (values per px), and the variance
    each has from the fit's scatter alone, the same shape. LinAlgError where the
    pixels span no plane."""
    X = np.c_[px - px.mean(axis=0), np.ones(len(px))]
    coef, *_ = np.linalg.lstsq(X, values, rcond=None)
    scatter = np.mean((values - X @ coef) ** 2, axis=0)  # () or (k,)
    return coef[:2], np.multiply.outer(np.diag(np.linalg.inv(X.T @ X))[:2], scatter)


def warp_pair(
    left: np.ndarray,
    right: np.ndarray,
    rect: Rectification,
    scale: float = 1.0,
    lens: Lens | None = None,
    right_lens: Lens | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Warp both recorded images onto the rectified canvas, optionally downscaled by
    ``scale``, through the ``lens`` (None: a distortion-free pinhole), the right image
    through ``right_lens`` where given.

    Returns float32 images of the canvas size times ``scale``; pixels from outside the
    source image are 0.
    """
    out = []
    for img, H, view_lens in ((left, rect.H_left, lens), (right, rect.H_right, right_lens or lens)):
        if scale != 1.0:
            # Area-average first so the warp does not alias, then one bilinear warp.
            small = (round(img.shape[1] * scale), round(img.shape[0] * scale))
            img = cv2.resize(img, small, interpolation=cv2.INTER_AREA)
        out.append(_warp(img, H, rect, scale, view_lens, cv2.INTER_LINEAR))
    return out[0], out[1]


def _warp(
    img: np.ndarray, H: np.ndarray, rect: Rectification, scale: float, lens: Lens | None,
    interpolation: int,
) -> np.ndarray:
    """``img`` (already at ``scale``) onto the ``scale``-resized canvas by the
    full-resolution homography ``H`` from ideal pixels, through the lens distortion."""
    S = scaling(scale)
    size = (round(rect.size[0] * scale), round(rect.size[1] * scale))
    if lens is None or lens.pinhole:  # a homography, the shift (if any) in it
        shift = np.eye(3) if lens is None else np.array([[1, 0, -lens.shift[0]],
                                                         [0, 1, -lens.shift[1]], [0, 0, 1]])
        return cv2.warpPerspective(img, S @ H @ shift @ np.linalg.inv(S), size,
                                   flags=interpolation)
    # Each canvas pixel's source: back through the homography to an ideal pixel, then
    # through the lens to where the camera recorded it (a smooth map: see smooth_map).
    back = np.linalg.inv(S @ H)

    def source(q: np.ndarray) -> np.ndarray:
        return apply_homography(S, lens.to_recorded(apply_homography(back, q)))

    mx, my = smooth_map(source, (0, size[0]), (0, size[1]))
    return cv2.remap(img, mx.astype(np.float32), my.astype(np.float32), interpolation,
                     borderMode=cv2.BORDER_CONSTANT, borderValue=0)


def footprints(
    rect: Rectification,
    image_size: tuple[int, int],
    scale: float,
    margin: int = 1,
    lens: Lens | None = None,
    right_lens: Lens | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Where the left and right images land on the ``scale``-resized rectified canvas:
    two (h, w) bool masks, eroded by ``margin`` px so matching windows stay inside;
    through ``lens`` (the right image through ``right_lens`` where given)."""
    small = (round(image_size[0] * scale), round(image_size[1] * scale))
    ones = np.full((small[1], small[0]), 255, np.uint8)
    kernel = np.ones((2 * margin + 1, 2 * margin + 1), np.uint8)
    masks = []
    for H, view_lens in ((rect.H_left, lens), (rect.H_right, right_lens or lens)):
        m = _warp(ones, H, rect, scale, view_lens, cv2.INTER_NEAREST)
        masks.append(cv2.erode(m, kernel) > 0)
    return masks[0], masks[1]


def scaling(scale: float) -> np.ndarray:
    """3x3 map from full-resolution to ``scale``-resized pixel coordinates (centres aligned)."""
    S = np.diag([scale, scale, 1.0])
    S[:2, 2] = 0.5 * scale - 0.5
    return S
