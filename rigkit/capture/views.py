"""What the on-site checks look at (:mod:`rigkit.capture.field`): each frame decoded
once and reduced to a check image, kept while the checks use it, and how another view
maps onto the left one.

A frame is decoded once for all its checks (its own, the later positions' against it,
the preview beside them); the left frame prepared for matching and the views' maps are
kept the same way, for the frames used last (``_KEPT``).
"""

from __future__ import annotations

import math
import threading
from collections.abc import Callable, Hashable
from dataclasses import dataclass
from typing import TypeVar

import cv2
import numpy as np

from rigkit.capture.model import DERIVED_DIR, Frame, Session
from rigkit.core.threads import ViewPool
from rigkit.imagefile.picture import CLIP_LEVEL
from rigkit.imagefile.rawio import is_raw, load_linear_grey, to_pipeline
from rigkit.pipeline.checks import MAX_RIGHT_SCALE_CHANGE, Parallax, measure_parallax
from rigkit.pipeline.features import Reference, match_to, prepare_left
from rigkit.pipeline.motion import view_motion
from rigkit.pipeline.rectify import pseudo_rectify
from rigkit.pipeline.settings import PipelineSettings

CHECK_SIDE_PX = 1024
"""Longest side of the reduced images the on-site checks work on, px."""


@dataclass(frozen=True)
class CheckFrame:
    """A frame as the on-site checks take it: ``image``, (h, w) float32 grey in [0, 255]
    (read-only), its longest side at most ``CHECK_SIDE_PX``; ``reduction``,
    full-resolution px per check px (>= 1); ``clipped``, the share of the
    full-resolution frame's pixels at or above :data:`CLIP_LEVEL`."""

    image: np.ndarray
    reduction: float
    clipped: float


@dataclass(frozen=True)
class ViewMap:
    """How another view maps onto the left one, in full-resolution pixels.

    ``scale``: other / left image size of the same object at the matches' mean depth,
    their depths' parallax taken out (:func:`rigkit.pipeline.motion.view_motion`);
    ``scale_sigma`` its standard error; ``roll_deg`` (the scene appears turned clockwise
    on screen by this much in the other view, degrees, image y down) is the
    homography's at the image centre; ``parallax``: the left/right
    disparities' spread, as processing measures it (:func:`measure_parallax`), where
    asked for and the views are the same size (else None); ``matches`` (sub-pixel
    tracks used); ``reduction``: full-resolution px per check-image px.
    """

    scale: float
    roll_deg: float
    parallax: Parallax | None
    matches: int
    reduction: float
    scale_sigma: float = 0.0


def decoded(session: Session, frame: Frame) -> np.ndarray:
    """A frame decoded: (H, W) float32 grey in [0, 1] of full scale
    (:func:`rigkit.imagefile.rawio.load_linear_grey`, RAW through the session's cache)."""
    return load_linear_grey(session.path / frame.file, session.path / DERIVED_DIR, frame.sha256)


def full_image(session: Session, frame: Frame) -> np.ndarray:
    """A frame at full resolution as the pipeline takes it: (H, W) float32 grey."""
    grey = decoded(session, frame)
    return to_pipeline([grey], linear=is_raw(session.path / frame.file), overwrite=True)[0]


K = TypeVar("K", bound=Hashable)
V = TypeVar("V")
_KEPT = 6
"""Frames (and left frames prepared, and view maps) the checks keep in memory, those
used last: the left frame the others are mapped onto, a burst's first frame and its
newest, the frames of the other positions. A check image is 3 MB; a prepared left
frame 6 MB."""
_lock = threading.Lock()


def kept(cache: dict[K, V], key: K, compute: Callable[[], V]) -> V:
    """``cache[key]``, computed first where missing; only the ``_KEPT`` used last stay."""
    with _lock:
        if key in cache:
            cache[key] = cache.pop(key)  # used last
            return cache[key]
    value = compute()
    with _lock:
        cache[key] = value
        while len(cache) > _KEPT:
            del cache[next(iter(cache))]
    return value


_CHECK_FRAMES: dict[str, CheckFrame] = {}
"""Frames decoded and reduced for the checks, by their SHA-256: a frame is decoded once
for all its checks (its own, the later positions' against it, the preview)."""
_REFERENCES: dict[str, Reference] = {}
"""Left check images prepared for matching (:func:`prepare_left`), by SHA-256."""
_VIEWS: dict[tuple[str, str, float, bool], ViewMap] = {}
"""View maps (:func:`map_views`) by the left and the other frame's SHA-256, the focal
length and whether the frame is a right one (moved sideways, its parallax asked for)."""


def check_frame(session: Session, frame: Frame) -> CheckFrame:
    """The :class:`CheckFrame` of ``frame``, decoded the first time only."""
    return kept(_CHECK_FRAMES, frame.sha256, lambda: _decode_for_checks(session, frame)[0])


def _decode_for_checks(session: Session, frame: Frame) -> tuple[CheckFrame, np.ndarray]:
    """``frame`` decoded: its :class:`CheckFrame`, and the frame at full resolution as
    :func:`full_image` gives it."""
    return _for_checks(decoded(session, frame), is_raw(session.path / frame.file))


def _for_checks(grey: np.ndarray, linear: bool) -> tuple[CheckFrame, np.ndarray]:
    """A decoded frame (``grey``: (H, W) float32 in [0, 1], scaled in place; ``linear``:
    from RAW) as its :class:`CheckFrame` and at full resolution as :func:`full_image`
    gives it."""
    clipped = np.count_nonzero(grey >= CLIP_LEVEL) / grey.size
    full = to_pipeline([grey], linear=linear, overwrite=True)[0]
    image, reduction = reduced(full)
    image.flags.writeable = False
    return CheckFrame(image, reduction, clipped), full


_FULL: dict[str, np.ndarray] = {}
"""The newest frame handed in at ingest at full resolution (:func:`admit`), by SHA-256,
until its shimmer is measured (:func:`decoded_with_full`): one frame at a time."""


def admit(sha256: str, grey: np.ndarray, linear: bool, keep_full: bool) -> CheckFrame:
    """A frame decoded on its way into the session (:func:`rigkit.capture.actions.
    staged_frame`; ``grey`` (H, W) float32 in [0, 1], scaled in place; ``linear``: from
    RAW) made its checks' :class:`CheckFrame`, kept by its SHA-256 for every check that
    follows: the burst comparison, its own checks, the later positions' against it. With
    ``keep_full`` (a burst's later frame, whose shimmer is measured at full resolution)
    the full-resolution frame is kept too, until its checks take it. So a frame that
    arrives is decoded once."""
    checked, full = _for_checks(grey, linear)
    kept(_CHECK_FRAMES, sha256, lambda: checked)
    with _lock:
        _FULL.clear()
        if keep_full:
            _FULL[sha256] = full
    return checked


def check_image(session: Session, frame: Frame) -> tuple[np.ndarray, float]:
    """A frame as (h, w) float32 grey in [0, 255] (read-only), its longest side at most
    ``CHECK_SIDE_PX``, and the reduction factor (full-resolution px per check px, >= 1)."""
    checked = check_frame(session, frame)
    return checked.image, checked.reduction


def reference(session: Session, left: Frame, pool: ViewPool | None = None) -> Reference:
    """The left ``frame``'s check image prepared for matching (:func:`prepare_left`, in
    ``pool``'s threads where given), the first time only."""
    image = check_frame(session, left).image
    return kept(_REFERENCES, left.sha256,
                 lambda: prepare_left(image, MATCH_POINTS, CHECK_MATCHING, pool))


def view_map(session: Session, position: str, left: Frame, frame: Frame) -> ViewMap:
    """How ``position``'s ``frame`` maps onto the ``left`` frame (:func:`map_views`: a
    back frame moved behind, with the parallax for a right frame), the first time only."""
    focal = session.rig().focal_px
    right = position == "right"

    def compute() -> ViewMap:
        first = check_frame(session, left)
        other = check_frame(session, frame).image
        return map_views(first.image, other, first.reduction, focal, reference(session, left),
                         axis="x" if right else "z", parallax=right)

    return kept(_VIEWS, (left.sha256, frame.sha256, focal, right), compute)


def reduced(image: np.ndarray, side_px: int = CHECK_SIDE_PX) -> tuple[np.ndarray, float]:
    """``image`` shrunk so its longest side is at most ``side_px``, and the factor."""
    reduction = max(1.0, max(image.shape) / side_px)
    if reduction > 1.0:
        size = (round(image.shape[1] / reduction), round(image.shape[0] / reduction))
        image = cv2.resize(image, size, interpolation=cv2.INTER_AREA)
    return image, reduction


MATCH_POINTS = 1500
"""Corners of the left check image tracked into the other view."""
CHECK_MATCHING = PipelineSettings(coarse_side_px=640)
"""How the checks match views: SIFT's coarse alignment on a 640-px copy of the check
images, which only starts the tracking of the corners at the check images' resolution
(what the checks measure on). On a full-resolution frame 0.4 s of CPU less per view
than at their 1024 px, and 700-1200 features agreeing on the alignment (12 needed)."""


def map_views(left: np.ndarray, other: np.ndarray, reduction: float, focal_px: float,
              ref: Reference | None = None, axis: str = "x", parallax: bool = True
              ) -> ViewMap:
    """How ``other`` maps onto ``left`` (check images, (h, w) float32, ``reduction``
    full-resolution px per px, the rig's full-resolution ``focal_px``): the scale of a
    view that moved along ``axis`` (``"x"`` beside the left one, ``"z"`` behind it) at
    the matches' mean depth with their depths' parallax taken out, as processing
    measures it (:func:`rigkit.pipeline.motion.view_motion`: a scene receding up the
    view shears and stretches an affine or homography map by more than the back view's
    magnification), the roll of the best homography at the image centre and, where
    ``parallax`` is asked for and the scale is a right view's, the left/right parallax
    as processing measures it (pseudo-rectified, so a camera only turned leaves none).
    ``ref``: ``left`` prepared for matching with ``MATCH_POINTS`` corners, where already
    done (:func:`rigkit.pipeline.features.prepare_left`). PipelineError if they do not
    match."""
    ref = ref or prepare_left(left, MATCH_POINTS, CHECK_MATCHING)
    matches = match_to(ref, other, "left/other", CHECK_MATCHING)
    a, b = matches.left.astype(np.float32), matches.other.astype(np.float32)
    similarity, _ = cv2.estimateAffinePartial2D(a, b, method=cv2.LMEDS)
    if similarity is None:
        similarity = matches.affine
    centre = np.array([(left.shape[1] - 1) / 2.0, (left.shape[0] - 1) / 2.0])
    local = _local_linear(a, b, (float(centre[0]), float(centre[1])), similarity[:, :2])
    motion = view_motion(matches, focal_px / reduction, centre, axis)
    scale = motion.scale
    measured = None
    if parallax and abs(scale - 1.0) <= MAX_RIGHT_SCALE_CHANGE:
        size = (left.shape[1], left.shape[0])
        rect = pseudo_rectify(matches, focal_px / reduction, size)
        measured = measure_parallax(matches, rect, reduction)
    return ViewMap(
        scale=scale,
        roll_deg=float(math.degrees(math.atan2(local[1, 0] - local[0, 1],
                                               local[0, 0] + local[1, 1]))),
        parallax=measured,
        matches=len(a),
        reduction=reduction,
        scale_sigma=motion.scale_sigma,
    )


def _local_linear(a: np.ndarray, b: np.ndarray, point: tuple[float, float],
                  fallback: np.ndarray) -> np.ndarray:
    """(2, 2) derivative at ``point`` (px) of the homography from points ``a`` to ``b``
    ((N, 2) each). A camera tilted between positions adds keystone: the scale then grows
    across the image by ~tilt x offset / f, a few 1e-4, as much as the back view's whole
    magnification signal (1 - m ~ C_lb / z ~ 7e-3 ... 1e-3). The homography models it;
    at the image centre (near the principal point) keystone adds no scale."""
    homography, _ = cv2.findHomography(a, b, cv2.LMEDS)
    if homography is None:
        return fallback
    x, y = point
    w = homography[2, 0] * x + homography[2, 1] * y + homography[2, 2]
    u = (homography[0, 0] * x + homography[0, 1] * y + homography[0, 2]) / w
    v = (homography[1, 0] * x + homography[1, 1] * y + homography[1, 2]) / w
    top = homography[:2, :2] - np.outer([u, v], homography[2, :2])
    return np.asarray(top / w, dtype=np.float64)


def decoded_with_full(session: Session, frame: Frame) -> np.ndarray | None:
    """Decodes ``frame`` for its checks (:func:`check_frame`) and gives it at full
    resolution too (as :func:`full_image`) where this decodes it or :func:`admit` kept
    it; None where it was decoded before (the full-resolution frame is not kept): one
    decoding for both."""
    with _lock:
        full = _FULL.pop(frame.sha256, None)
        known = frame.sha256 in _CHECK_FRAMES
    if known:
        check_frame(session, frame)
        return full
    checked, full = _decode_for_checks(session, frame)
    kept(_CHECK_FRAMES, frame.sha256, lambda: checked)
    return full
