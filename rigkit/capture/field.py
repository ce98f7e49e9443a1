"""On-site checks of a capture as it is taken, frame by frame, at reduced resolution.

What the field TUI (``rigkit field``) shows after every frame, computed here so that any
front end gets the same answers:

* the frame's EXIF against the frames already taken and the rig profile
  (:func:`rigkit.capture.checks.check_capture`'s rules for the frames present so far);
* clipped highlights (a saturated sensor leaves nothing to match);
* from the second frame of a burst on: the heat shimmer between the position's first
  frame and each later one, measured at full resolution, and the burst length their
  median calls for at the profile's nominal range;
* after the right frame: parallax, scale and a plausible rotation. The parallax is
  processing's own rule (:meth:`rigkit.pipeline.checks.Parallax.problem`): the matches
  pseudo-rectified (a camera only turned then leaves nothing but the matches' noise)
  and the spread of their disparities against that noise. A spread no larger than
  noise means the tripod was not moved or the same view was taken twice; one clear of
  noise but too small for depth, a scene with little depth in view;
* after the back frame: its magnification m against the left view, below 1 because the
  back camera is ``C_lb`` behind, and the range it implies, z = m C_lb / (1 - m) (an
  object at depth z from the left camera is at z + C_lb from the back one; the paper's
  Sec. 3.3 resolves the depth ambiguity with this scale); and, with the right frame
  taken, that the two are not swapped (the pipeline's rule, so ``rigkit depth`` and
  processing refuse what is flagged here).

A frame that has no picture, is another frame of the session or has the wrong size
never gets this far: :func:`rigkit.capture.actions.add_frame` refuses it on arrival.

A position holds one frame or a burst of several; :func:`frames_at` and
:func:`add_position_frame` are how the field workflow reads and grows it.
"""

from __future__ import annotations

import math
import statistics
import threading
from collections.abc import Callable, Hashable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TypeVar

import cv2
import numpy as np

from rigkit.capture.actions import add_frame
from rigkit.capture.checks import UNCHECKED, check_exif
from rigkit.capture.picture import CLIP_LEVEL
from rigkit.capture.rawio import is_raw, load_linear_grey, to_pipeline
from rigkit.capture.session import DERIVED_DIR, POSITIONS, Frame, Session
from rigkit.core.files import file_sha256
from rigkit.core.threads import ViewPool
from rigkit.errors import RigkitError
from rigkit.pipeline.checks import (
    MAX_RIGHT_SCALE_CHANGE,
    Parallax,
    implied_range_m,
    measure_parallax,
    roles_problem,
)
from rigkit.pipeline.features import Reference, match_to, prepare_left
from rigkit.pipeline.rectify import pseudo_rectify
from rigkit.pipeline.settings import PipelineSettings
from rigkit.pipeline.shimmer import Shimmer, ShimmerStart, shimmer_from, shimmer_start
from rigkit.rig.bursts import burst_advice
from rigkit.rig.findings import Finding
from rigkit.rig.profile import RigProfile

CHECK_SIDE_PX = 1024
"""Longest side of the reduced images the on-site checks work on, px."""
MAX_BURST_SCALE_CHANGE = 0.002
"""The frames of one position's burst are one view: a scale change beyond this (the
back position's magnification is 1 - C_lb / z, 0.007 at 300 m) is another position."""
MAX_ROLL_DEG = 10.0
"""Largest plausible roll between two positions; more means a camera turned on its side."""
MAX_BLOWN = 0.01
"""Largest share of clipped pixels (:data:`rigkit.capture.picture.CLIP_LEVEL`) before the
highlights count as blown and the frame should be taken again."""
RANGE_FACTOR = 2.0
"""An implied range more than this factor from the profile's nominal range is suspect."""


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

    ``scale`` (other / left image size of the same object) and ``roll_deg`` (the scene
    appears turned clockwise on screen by this much in the other view, degrees, image y
    down) are the homography's at the image centre; ``parallax``: the left/right
    disparities' spread, as processing measures it (:func:`measure_parallax`), where
    asked for and the views are the same size (else None); ``matches`` (sub-pixel
    tracks used); ``reduction``: full-resolution px per check-image px.
    """

    scale: float
    roll_deg: float
    parallax: Parallax | None
    matches: int
    reduction: float


# -- one place that knows how many frames a position holds -------------------------------


def frames_at(session: Session, position: str) -> tuple[Frame, ...]:
    """The frames recorded for ``position``, oldest first (empty if none yet)."""
    return session.bursts.get(position, ())


def burst_misfit(session: Session, position: str, path: Path) -> str | None:
    """Why the frame at ``path`` does not belong to ``position``'s burst, or None: the
    frames of a burst show one view, shifted a little by the tripod's sway, while a
    frame from another position shows the scene with parallax (the right one) or
    magnified (the back one). None too for the first frame of a position, and for a
    file that cannot be read (adding it says why)."""
    frames = frames_at(session, position)
    if not frames:
        return None
    try:
        cache = session.path / DERIVED_DIR
        grey = load_linear_grey(path, cache, file_sha256(path), session.rig().image_size)
        new = _reduced(to_pipeline([grey], linear=is_raw(path), overwrite=True)[0])[0]
        first = check_frame(session, frames[0])
        view = map_views(first.image, new, first.reduction, session.rig().focal_px,
                         reference(session, frames[0]))
    except RigkitError:
        return None
    moved = view.parallax is not None and view.parallax.moved
    if not moved and abs(view.scale - 1.0) <= MAX_BURST_SCALE_CHANGE:
        return None
    parallax = "" if view.parallax is None else f"parallax {view.parallax.spread_px:.1f} px, "
    return (f"{path.name} does not match the {position} burst ({parallax}scale "
            f"{view.scale:.4f}): it looks taken from another position")


def add_position_frame(session: Session, position: str, path: Path,
                       retake: bool | None = None) -> Session:
    """Record ``path`` as a frame of ``position`` (copied into ``raw/``, never moved): its
    first, one more of its burst, or the retake that replaces the position's frames
    (their files stay in ``raw/``): when ``retake`` says so or, left None, when the
    position's newest frame failed its on-site checks."""
    if retake is None:
        retake = newest_failed(session, position)
    return add_frame(session, position, path, burst=not retake, replace_existing=retake)


def newest_failed(session: Session, position: str) -> bool:
    """Whether ``position``'s newest frame failed its on-site checks: the next frame is
    then its retake, and never compared with it as a burst (a failed frame is nobody's
    reference)."""
    return bool(frames_at(session, position)) and not all_ok(onsite_checks(session, position))


def resume_step(session: Session) -> str:
    """The step ``rigkit field`` opens ``session`` at: the one it was on when it stopped
    (``session.field_step``), unless that needs frames the session lacks (then the first
    position without one, :func:`next_step`); where no step was recorded, the rig while no
    frame is taken, else :func:`next_step`."""
    derived = next_step(session)
    step = session.field_step
    if step is None:
        return "rig" if derived == "left" else derived
    if step in ("targets", "process") and derived in POSITIONS:
        return derived
    return step


def next_step(session: Session) -> str:
    """Where a capture stands: the first position without a frame, then ``targets``
    while no target has a reading, then ``process``."""
    for position in POSITIONS:
        if not frames_at(session, position):
            return position
    if not any(target.readings for target in session.targets):
        return "targets"
    return "process"


# -- checks ---------------------------------------------------------------------------------


def decoded(session: Session, frame: Frame) -> np.ndarray:
    """A frame decoded: (H, W) float32 grey in [0, 1] of full scale
    (:func:`rigkit.capture.rawio.load_linear_grey`, RAW through the session's cache)."""
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


def _kept(cache: dict[K, V], key: K, compute: Callable[[], V]) -> V:
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
_VIEWS: dict[tuple[str, str, float | None], ViewMap] = {}
"""View maps (:func:`map_views`) by the left and the other frame's SHA-256 and the focal
length that asks for the parallax."""


def check_frame(session: Session, frame: Frame) -> CheckFrame:
    """The :class:`CheckFrame` of ``frame``, decoded the first time only."""
    return _kept(_CHECK_FRAMES, frame.sha256, lambda: _decode_for_checks(session, frame)[0])


def _decode_for_checks(session: Session, frame: Frame) -> tuple[CheckFrame, np.ndarray]:
    """``frame`` decoded: its :class:`CheckFrame`, and the frame at full resolution as
    :func:`full_image` gives it."""
    grey = decoded(session, frame)
    clipped = np.count_nonzero(grey >= CLIP_LEVEL) / grey.size
    linear = is_raw(session.path / frame.file)
    full = to_pipeline([grey], linear=linear, overwrite=True)[0]
    image, reduction = _reduced(full)
    image.flags.writeable = False
    return CheckFrame(image, reduction, clipped), full


def _newest_for_checks(session: Session, position: str) -> np.ndarray | None:
    """Decodes ``position``'s newest frame for its checks (:func:`check_frame`) and
    returns it at full resolution where its shimmer against the burst's first frame is
    still to be measured (:func:`shimmer_check`), else None: one decoding for both."""
    frames = frames_at(session, position)
    newest = frames[-1]
    due = len(frames) > 1 and (frames[0].sha256, newest.sha256) not in _MEASURED
    if not due or newest.sha256 in _CHECK_FRAMES:
        check_frame(session, newest)
        return None
    checked, full = _decode_for_checks(session, newest)
    _kept(_CHECK_FRAMES, newest.sha256, lambda: checked)
    return full


def check_image(session: Session, frame: Frame) -> tuple[np.ndarray, float]:
    """A frame as (h, w) float32 grey in [0, 255] (read-only), its longest side at most
    ``CHECK_SIDE_PX``, and the reduction factor (full-resolution px per check px, >= 1)."""
    checked = check_frame(session, frame)
    return checked.image, checked.reduction


def reference(session: Session, left: Frame, pool: ViewPool | None = None) -> Reference:
    """The left ``frame``'s check image prepared for matching (:func:`prepare_left`, in
    ``pool``'s threads where given), the first time only."""
    image = check_frame(session, left).image
    return _kept(_REFERENCES, left.sha256,
                 lambda: prepare_left(image, MATCH_POINTS, CHECK_MATCHING, pool))


def view_map(session: Session, position: str, left: Frame, frame: Frame) -> ViewMap:
    """How ``position``'s ``frame`` maps onto the ``left`` frame (:func:`map_views`, with
    the parallax for a right frame), the first time only."""
    focal = session.rig().focal_px if position == "right" else None

    def compute() -> ViewMap:
        first = check_frame(session, left)
        other = check_frame(session, frame).image
        return map_views(first.image, other, first.reduction, focal, reference(session, left))

    return _kept(_VIEWS, (left.sha256, frame.sha256, focal), compute)


def _reduced(image: np.ndarray, side_px: int = CHECK_SIDE_PX) -> tuple[np.ndarray, float]:
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


def map_views(left: np.ndarray, other: np.ndarray, reduction: float = 1.0,
              focal_px: float | None = None, ref: Reference | None = None) -> ViewMap:
    """How ``other`` maps onto ``left`` (check images, (h, w) float32, ``reduction``
    full-resolution px per px): the scale and roll of the best homography at the image
    centre and, given the full-resolution ``focal_px`` and views of the same size, the
    left/right parallax as processing measures it (pseudo-rectified, so a camera only
    turned leaves none). ``ref``: ``left`` prepared for matching with ``MATCH_POINTS``
    corners, where already done (:func:`rigkit.pipeline.features.prepare_left`).
    PipelineError if they do not match."""
    ref = ref or prepare_left(left, MATCH_POINTS, CHECK_MATCHING)
    matches = match_to(ref, other, "left/other", CHECK_MATCHING)
    a, b = matches.left.astype(np.float32), matches.other.astype(np.float32)
    similarity, _ = cv2.estimateAffinePartial2D(a, b, method=cv2.LMEDS)
    if similarity is None:
        similarity = matches.affine
    centre = ((left.shape[1] - 1) / 2.0, (left.shape[0] - 1) / 2.0)
    local = _local_linear(a, b, centre, similarity[:, :2])
    scale = float(math.sqrt(abs(np.linalg.det(local))))
    parallax = None
    if focal_px is not None and abs(scale - 1.0) <= MAX_RIGHT_SCALE_CHANGE:
        size = (left.shape[1], left.shape[0])
        rect = pseudo_rectify(matches, focal_px / reduction, size)
        parallax = measure_parallax(matches, rect, reduction)
    return ViewMap(
        scale=scale,
        roll_deg=float(math.degrees(math.atan2(local[1, 0] - local[0, 1],
                                               local[0, 0] + local[1, 1]))),
        parallax=parallax,
        matches=len(a),
        reduction=reduction,
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


def exif_check(session: Session, position: str) -> Finding:
    """The position's frame's EXIF against the other frames taken and the profile.

    Fields the camera did not record are noted, not failed; a rendered frame without
    any EXIF passes with a note that nothing was checked.
    """
    paths = {pos: session.path / frames_at(session, pos)[-1].file
             for pos in POSITIONS if frames_at(session, pos)}
    findings = [f for f in check_exif(session.rig(), paths) if f.frame in (position, None)]
    problems = [f for f in findings if f.code not in UNCHECKED]
    if problems:
        return Finding(
            "exif", "; ".join(f.message for f in problems),
            redo="set the camera back to the same zoom, exposure and ISO, and take this frame "
            "again",
        )
    if any(f.code == "capture.no_exif" for f in findings):
        return Finding("exif", "no EXIF in this frame (rendered?): settings not checked",
                       ok=True)
    missing = sorted({f.field or "" for f in findings})
    note = f" (not recorded: {', '.join(missing)})" if missing else ""
    return Finding("exif", f"EXIF agrees with the other frames and the profile{note}", ok=True)


def exposure_check(session: Session, frame: Frame) -> Finding:
    """Clipped highlights: where the sensor saturated there is no texture to match, and
    a frame too bright for one position is so for all (they must share the exposure)."""
    clipped = check_frame(session, frame).clipped
    if clipped <= MAX_BLOWN:
        return Finding("exposure", f"highlights: {100 * clipped:.2f} % clipped", ok=True)
    return Finding(
        "exposure", f"{100 * clipped:.1f} % of the frame is clipped (blown highlights)",
        redo="lower the exposure and take the frames again from the left position (all "
        "three must share it)",
    )


def right_checks(view: ViewMap, profile: RigProfile | None = None) -> list[Finding]:
    """Roll, scale and (where the scale is a right view's) parallax, by processing's
    rule (:meth:`Parallax.problem`), of the right view against the left one. With the
    rig ``profile``'s nominal range, a right view nearer the magnification a back view
    shows there than 1 is taken for one taken behind."""
    checks = [_roll_check(view, "right")]
    scale = _right_scale_check(view.scale, profile)
    if scale is not None:
        return [*checks, scale]  # a magnified view's parallax means nothing
    if view.parallax is not None:
        problem = view.parallax.problem()
        checks.insert(0, Finding("parallax", problem[0], redo=problem[1]) if problem else
                      Finding("parallax", f"parallax {view.parallax.spread_px:.1f} px across "
                              "the scene", ok=True))
    return checks


def _right_scale_check(scale: float, profile: RigProfile | None) -> Finding | None:
    if abs(scale - 1.0) > MAX_RIGHT_SCALE_CHANGE:
        return Finding("scale", f"right view {scale:.4f}× the left one: the zoom changed",
                       redo="set the zoom back to the left frame's and take the right frame "
                       "again")
    if profile is None or profile.nominal_range_m is None:
        return None
    z = profile.nominal_range_m
    back = z / (z + profile.baseline_lb.value_m)
    if scale >= (1.0 + back) / 2:
        return None
    return Finding("scale", f"right view {scale:.4f}× the left one, nearer the {back:.4f}× a "
                   f"back view shows at {z:g} m: was it taken behind the left position?",
                   redo="take the right frame beside the left position (C_lr to its right), "
                   "at the same zoom")


def back_checks(view: ViewMap, profile: RigProfile) -> list[Finding]:
    """Magnification of the back view (< 1) and the range it implies."""
    c_lb = profile.baseline_lb.value_m
    checks = [_roll_check(view, "back")]
    if view.scale >= 1.0:
        checks.append(Finding(
            "magnification", f"back view {view.scale:.4f}×: not smaller than the left view",
            redo=f"take the back frame {c_lb:g} m behind the left position, same zoom",
        ))
        return checks
    z = implied_range_m(view.scale, c_lb)
    text = f"back view {view.scale:.4f}× → ~{_round_range(z)} m at C_lb = {c_lb:.1f} m"
    nominal = profile.nominal_range_m
    if nominal is not None and not nominal / RANGE_FACTOR <= z <= nominal * RANGE_FACTOR:
        checks.append(Finding(
            "magnification", f"{text}, far from the planned {nominal:g} m",
            redo=f"check that the back position is {c_lb:g} m behind the left one and the "
            "zoom is unchanged, then take the back frame again",
        ))
    else:
        checks.append(Finding("magnification", text, ok=True))
    return checks


def _roll_check(view: ViewMap, position: str) -> Finding:
    if abs(view.roll_deg) <= MAX_ROLL_DEG:
        return Finding("rotation", f"{position} view rolled {view.roll_deg:+.2f} deg", ok=True)
    return Finding(
        "rotation", f"{position} view rolled {view.roll_deg:+.1f} deg against the left one",
        redo=f"level the camera as for the left frame and take the {position} frame again",
    )


def _round_range(z: float) -> str:
    """A range to two significant figures, as the magnification fixes it (~1 %)."""
    return f"{float(f'{z:.2g}'):g}" if z >= 100 else f"{z:.0f}"


def shimmer_check(session: Session, position: str, newest: np.ndarray | None = None
                  ) -> Finding | None:
    """Heat shimmer measured at full resolution between the first frame of
    ``position``'s burst and each later one (:mod:`rigkit.pipeline.shimmer`), their
    median, and the burst length that median calls for to keep the offset within 0.3 %
    of depth at the profile's nominal range nine captures out of ten
    (:func:`rigkit.rig.bursts.burst_advice`). One pair's figure moves with the air from
    frame to frame (advice of 4, 5 and 6 frames for one capture); the median settles as
    the burst grows, and the range of the pairs is shown with it. None for a single
    frame. Always ok: shimmer is the air's fault, not the frame's. ``newest``: the
    newest frame as :func:`full_image` gives it, where already decoded."""
    frames = frames_at(session, position)
    if len(frames) < 2:
        return None
    measured: list[Shimmer] = []
    failure = ""
    for number, frame in enumerate(frames[1:], 2):
        given = newest if number == len(frames) else None
        try:
            measured.append(_pair_shimmer(session, frames[0], frame, number, given))
        except RigkitError as exc:
            failure = str(exc)
    if not measured:
        return Finding("shimmer", f"heat shimmer not measured: {failure}", ok=True)
    shimmer = _median_shimmer(measured)
    where = f"{position} frames 1 and {len(frames)}"
    if len(measured) > 1:
        rms = sorted(m.rms_px for m in measured)
        where = (f"{position} frame 1 against {len(measured)} others: median, "
                 f"{rms[0]:.2f}-{rms[-1]:.2f} px")
    profile = session.rig()
    z = profile.nominal_range_m
    if z is None:
        return Finding("shimmer", f"heat shimmer {shimmer.rms_px:.2f} px RMS ({where}); a "
                       "nominal range in the rig profile would give the burst length to "
                       "take", ok=True)
    return Finding("shimmer", burst_advice(profile, shimmer, where, z)[0], ok=True)


_MEASURED: dict[tuple[str, str], Shimmer] = {}
"""Shimmer measured between two frames, by their SHA-256: each frame of a burst is
measured against the first once, not again for every frame after it."""


_STARTS: dict[str, ShimmerStart] = {}
"""Bursts' first frames prepared for measuring the shimmer (:func:`shimmer_start`), by
SHA-256: decoded once for all the burst's later frames."""


def _pair_shimmer(session: Session, first: Frame, other: Frame, number: int,
                  image: np.ndarray | None = None) -> Shimmer:
    """:func:`rigkit.pipeline.shimmer.measure_shimmer` between a burst's ``first`` frame
    and its ``number``-th, ``other`` (``image``: it as :func:`full_image` gives it,
    where already decoded)."""
    key = (first.sha256, other.sha256)
    if key not in _MEASURED:
        where = f"{other.position} frames 1 and {number}"
        start = _kept(_STARTS, first.sha256,
                      lambda: shimmer_start(full_image(session, first), where))
        image = full_image(session, other) if image is None else image
        _MEASURED[key] = shimmer_from(start, image, where)
    return _MEASURED[key]


def _median_shimmer(measured: Sequence[Shimmer]) -> Shimmer:
    """The median of each figure of ``measured`` (the correlation length of those that
    found one; NaN where none did)."""
    corr = [m.corr_px for m in measured if math.isfinite(m.corr_px)]
    return Shimmer(
        rms_px=statistics.median(m.rms_px for m in measured),
        corr_px=statistics.median(corr) if corr else math.nan,
        tracker_px=statistics.median(m.tracker_px for m in measured),
        points=min(m.points for m in measured),
    )


def onsite_checks(session: Session, position: str) -> list[Finding]:
    """Every check for the newest frame of ``position`` (which must have one). Each frame
    is decoded once (:func:`check_frame`), the left one prepared for matching once and
    each view mapped onto it once, for all the checks that need them, these and later
    ones (the back frame's roles check takes the right frame's map); what is not known
    yet is found side by side. A failure shows where the checks in turn need that frame,
    not before."""
    newest = {p: frames_at(session, p)[-1] for p in POSITIONS if frames_at(session, p)}
    compared = position != "left" and "left" in newest
    with ViewPool() as pool:
        shown = pool.submit(_newest_for_checks, session, position)
        left = pool.submit(check_frame, session, newest["left"]) if compared else None
        full = shown.result()
        checks = [exif_check(session, position), exposure_check(session, newest[position])]
        shimmer = shimmer_check(session, position, full)
        del full
        if shimmer is not None:
            checks.append(shimmer)
        if left is None:
            return checks
        left.result()
        reference(session, newest["left"], pool)
        mapped = [position] + (["right"] if position == "back" and "right" in newest else [])
        views = {p: pool.submit(view_map, session, p, newest["left"], newest[p])
                 for p in mapped}
        try:
            view = views[position].result()
        except RigkitError as exc:
            return [*checks, Finding("match", str(exc), redo=f"aim at the left frame's scene "
                                     f"and take the {position} frame")]
        if position == "right":
            return [*checks, *right_checks(view, session.rig())]
        back = back_checks(view, session.rig())
        if all_ok(back) and "right" in views:  # magnified: is the right one less so?
            back += _roles_check(views["right"].result(), view,
                                 session.rig().baseline_lb.value_m)
        return [*checks, *back]


def view_of(session: Session, position: str) -> ViewMap:
    """How ``position``'s newest frame maps onto the left one's (:func:`view_map`)."""
    return view_map(session, position, frames_at(session, "left")[-1],
                    frames_at(session, position)[-1])


def _roles_check(right: ViewMap, back: ViewMap, baseline_lb_m: float) -> list[Finding]:
    """A failed check where the right and back frames look swapped (one rule with the
    pipeline's, :func:`rigkit.pipeline.checks.roles_problem`)."""
    problem = roles_problem(right.scale, back.scale, baseline_lb_m)
    if problem is None:
        return []
    return [Finding("roles", problem, redo="take the right frame beside the left position "
                    "and the back frame behind it, then replace the frames that are swapped")]


def all_ok(checks: Sequence[Finding]) -> bool:
    return all(check.ok for check in checks)
