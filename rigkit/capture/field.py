"""On-site checks of a capture as it is taken, frame by frame, at reduced resolution.

What the field TUI (``rigkit field``) shows after every frame, computed here so that any
front end gets the same answers:

* the frame's EXIF against the frames already taken and the rig profile
  (:func:`rigkit.capture.checks.check_capture`'s rules for the frames present so far);
* clipped highlights (a saturated sensor leaves nothing to match);
* from the second frame of a burst on: the heat shimmer between the position's first
  and newest frame, measured at full resolution, and the burst length it calls for at
  the profile's nominal range;
* after the right frame: parallax and a plausible rotation. Left and right views of a
  distant scene differ by a near-similarity (shift, small roll, scale ~1) plus the
  depth-dependent parallax; a similarity fitted to sub-pixel matches leaves that
  parallax as residual. No residual means the tripod was not moved (a pure rotation of
  a telephoto camera is a similarity to a small fraction of a pixel) or the same view
  was taken twice;
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
from collections.abc import Sequence
from dataclasses import dataclass
from datetime import UTC, datetime
from pathlib import Path

import cv2
import numpy as np

from rigkit.capture.actions import add_frame
from rigkit.capture.checks import UNCHECKED, check_exif
from rigkit.capture.picture import CLIP_LEVEL
from rigkit.capture.rawio import is_raw, load_linear_grey, to_pipeline
from rigkit.capture.session import DERIVED_DIR, POSITIONS, Frame, LaserReading, Session
from rigkit.core.files import file_sha256
from rigkit.errors import RigkitError
from rigkit.pipeline.checks import MAX_RIGHT_SCALE_CHANGE, implied_range_m, roles_problem
from rigkit.pipeline.features import match_views
from rigkit.pipeline.shimmer import measure_shimmer
from rigkit.rangefinder.framing import Reading, escape_bytes
from rigkit.rig.bursts import burst_advice
from rigkit.rig.findings import Finding
from rigkit.rig.profile import RigProfile

CHECK_SIDE_PX = 1024
"""Longest side of the reduced images the on-site checks work on, px."""
MIN_PARALLAX_PX = 0.4
"""Least parallax spread (10th to 90th percentile of the residual), in check-image px, for
the right view to count as taken from another place: a camera turned on its tripod
left ~0.2 px (tracking and sensor noise) in synthetic tests, a 2 m move at 300 m 0.75 px
at 384 px wide and far more at full size."""
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
class ViewMap:
    """How another view maps onto the left one, in full-resolution pixels.

    ``scale`` (other / left image size of the same object) and ``roll_deg`` (the scene
    appears turned clockwise on screen by this much in the other view, degrees, image y
    down) are the homography's at the image centre; ``parallax_px`` (spread of the
    residual after the best similarity: 10th to 90th percentile of its x component, px
    of the full image), ``matches`` (sub-pixel tracks used).
    """

    scale: float
    roll_deg: float
    parallax_px: float
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
        new = _reduced(to_pipeline([grey], linear=is_raw(path))[0])[0]
        first, reduction = check_image(session, frames[0])
        view = map_views(first, new, reduction)
    except RigkitError:
        return None
    if (view.parallax_px < MIN_PARALLAX_PX * reduction
            and abs(view.scale - 1.0) <= MAX_BURST_SCALE_CHANGE):
        return None
    return (f"{path.name} does not match the {position} burst (parallax "
            f"{view.parallax_px:.1f} px, scale {view.scale:.4f}): it looks taken from "
            "another position")


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


TYPO_SPREAD = 0.05
"""A typed range this far (5 %) from the target's other readings' median is doubted:
one target's readings agree within the laser's metre."""
TYPO_FACTOR = 1.5
"""A target's first typed range more than this factor from the back view's implied
range or the profile's planned one is doubted (a 3011 typed for 301.1)."""


def reading_doubt(range_m: float, others: Sequence[float], implied_m: float | None,
                  planned_m: float | None) -> str | None:
    """Why a range typed for a target looks like a typo, or None: far from the target's
    other readings (m) where it has some, else from the range the back view implied or
    the profile's planned range (m, None where unknown)."""
    if others:
        middle = statistics.median(others)
        if abs(range_m - middle) > TYPO_SPREAD * middle:
            return f"{range_m:g} m is far from this target's other readings ({middle:.1f} m)"
        return None
    for what, reference in (("the back view implied", implied_m),
                            ("the profile plans", planned_m)):
        if reference and not reference / TYPO_FACTOR <= range_m <= reference * TYPO_FACTOR:
            return f"{range_m:g} m is far from the ~{reference:.0f} m {what}"
    return None


def implied_range(session: Session) -> float | None:
    """The range (m) the back frame's magnification implies against the left frame,
    None without both or where they cannot be matched."""
    if not (frames_at(session, "left") and frames_at(session, "back")):
        return None
    try:
        left, reduction = check_image(session, frames_at(session, "left")[-1])
        view = _view_of(session, "back", left, reduction)
    except RigkitError:
        return None
    z = implied_range_m(view.scale, session.rig().baseline_lb.value_m)
    return z if math.isfinite(z) else None


def reading_from_device(reading: Reading, source: str) -> LaserReading:
    """A rangefinder's reading as the session records it; ``source`` is
    ``<protocol>:<port>``."""
    return LaserReading(
        slope_distance_m=reading.slope_distance_m,
        time_utc=datetime.fromtimestamp(reading.timestamp, UTC).strftime("%Y-%m-%dT%H:%M:%SZ"),
        source=source,
        inclination_deg=reading.inclination_deg,
        raw=escape_bytes(reading.raw),
        azimuth_deg=reading.azimuth_deg,
    )


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


def full_image(session: Session, frame: Frame) -> np.ndarray:
    """A frame at full resolution as the pipeline takes it: (H, W) float32 grey."""
    path = session.path / frame.file
    grey = load_linear_grey(path, session.path / DERIVED_DIR, frame.sha256)
    return to_pipeline([grey], linear=is_raw(path))[0]


def check_image(session: Session, frame: Frame, side_px: int = CHECK_SIDE_PX
                ) -> tuple[np.ndarray, float]:
    """A frame as (h, w) float32 grey in [0, 255], its longest side at most ``side_px``,
    and the reduction factor (full-resolution px per check px, >= 1)."""
    return _reduced(full_image(session, frame), side_px)


def _reduced(image: np.ndarray, side_px: int = CHECK_SIDE_PX) -> tuple[np.ndarray, float]:
    """``image`` shrunk so its longest side is at most ``side_px``, and the factor."""
    reduction = max(1.0, max(image.shape) / side_px)
    if reduction > 1.0:
        size = (round(image.shape[1] / reduction), round(image.shape[0] / reduction))
        image = cv2.resize(image, size, interpolation=cv2.INTER_AREA)
    return image, reduction


def map_views(left: np.ndarray, other: np.ndarray, reduction: float = 1.0) -> ViewMap:
    """Fit a similarity (scale, roll, shift) from ``left`` to ``other`` (check images,
    (h, w) float32) and measure what it leaves; PipelineError if they do not match."""
    matches = match_views(left, other, "left/other", n_points=1500)
    a, b = matches.left.astype(np.float32), matches.other.astype(np.float32)
    similarity, _ = cv2.estimateAffinePartial2D(a, b, method=cv2.LMEDS)
    if similarity is None:
        similarity = matches.affine
    residual = b - (a @ similarity[:, :2].T + similarity[:, 2])
    low, high = np.percentile(residual[:, 0], [10, 90])
    centre = ((left.shape[1] - 1) / 2.0, (left.shape[0] - 1) / 2.0)
    local = _local_linear(a, b, centre, similarity[:, :2])
    return ViewMap(
        scale=float(math.sqrt(abs(np.linalg.det(local)))),
        roll_deg=float(math.degrees(math.atan2(local[1, 0] - local[0, 1],
                                               local[0, 0] + local[1, 1]))),
        parallax_px=float(high - low) * reduction,
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
    path = session.path / frame.file
    grey = load_linear_grey(path, session.path / DERIVED_DIR, frame.sha256)
    clipped = float(np.mean(grey >= CLIP_LEVEL))
    if clipped <= MAX_BLOWN:
        return Finding("exposure", f"highlights: {100 * clipped:.2f} % clipped", ok=True)
    return Finding(
        "exposure", f"{100 * clipped:.1f} % of the frame is clipped (blown highlights)",
        redo="lower the exposure and take the frames again from the left position (all "
        "three must share it)",
    )


def right_checks(view: ViewMap) -> list[Finding]:
    """Parallax, roll and scale of the right view against the left one."""
    move = "move the tripod C_lr to the right of the left position and take the right frame"
    parallax_ok = view.parallax_px >= MIN_PARALLAX_PX * view.reduction
    checks = [
        Finding("parallax", f"parallax {view.parallax_px:.1f} px across the scene", ok=True)
        if parallax_ok else Finding(
            "parallax",
            f"no parallax ({view.parallax_px:.2f} px): the tripod was not moved, or the "
            "same view was taken twice", redo=move,
        ),
        _roll_check(view, "right"),
    ]
    if abs(view.scale - 1.0) > MAX_RIGHT_SCALE_CHANGE:
        checks.append(Finding(
            "scale", f"right view {view.scale:.4f}× the left one: the zoom changed",
            redo="set the zoom back to the left frame's and take the right frame again",
        ))
    return checks


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


def shimmer_check(session: Session, position: str) -> Finding | None:
    """Heat shimmer measured between the first and the newest frame of ``position``'s
    burst at full resolution (:mod:`rigkit.pipeline.shimmer`), and the burst length
    that keeps the offset within 0.3 % of depth at the profile's nominal range in nine
    captures out of ten (:func:`rigkit.rig.budget.frames_for_offset`). None for a
    single frame. Always ok: shimmer is the air's fault, not the frame's."""
    frames = frames_at(session, position)
    if len(frames) < 2:
        return None
    first = full_image(session, frames[0])
    where = f"{position} frames 1 and {len(frames)}"
    try:
        shimmer = measure_shimmer(first, full_image(session, frames[-1]), where)
    except RigkitError as exc:
        return Finding("shimmer", f"heat shimmer not measured: {exc}", ok=True)
    profile = session.rig()
    z = profile.nominal_range_m
    if z is None:
        return Finding("shimmer", f"heat shimmer {shimmer.rms_px:.2f} px RMS ({where}); a "
                       "nominal range in the rig profile would give the burst length to "
                       "take", ok=True)
    return Finding("shimmer", burst_advice(profile, shimmer, where, z)[0], ok=True)


def onsite_checks(session: Session, position: str) -> list[Finding]:
    """Every check for the newest frame of ``position`` (which must have one)."""
    checks = [exif_check(session, position),
              exposure_check(session, frames_at(session, position)[-1])]
    shimmer = shimmer_check(session, position)
    if shimmer is not None:
        checks.append(shimmer)
    if position == "left" or not frames_at(session, "left"):
        return checks
    left, reduction = check_image(session, frames_at(session, "left")[-1])
    try:
        view = _view_of(session, position, left, reduction)
    except RigkitError as exc:
        return [*checks, Finding("match", str(exc), redo=f"aim at the left frame's scene and "
                                 f"take the {position} frame")]
    if position == "right":
        return [*checks, *right_checks(view)]
    back = back_checks(view, session.rig())
    if all_ok(back) and frames_at(session, "right"):  # magnified: is the right one less so?
        right = _view_of(session, "right", left, reduction)
        back += _roles_check(right, view, session.rig().baseline_lb.value_m)
    return [*checks, *back]


def _view_of(session: Session, position: str, left: np.ndarray, reduction: float) -> ViewMap:
    """How ``position``'s newest frame maps onto the left check image ``left``."""
    other, _ = check_image(session, frames_at(session, position)[-1])
    return map_views(left, other, reduction)


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
