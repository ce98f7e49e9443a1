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
  noise but under half a pixel, a scene with little depth in view, said but not
  refused (the back view gives a flat scene's range);
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
What the checks look at, each frame decoded once and reduced, and how another view
maps onto the left one, is :mod:`rigkit.capture.views`.
"""

from __future__ import annotations

import math
import statistics
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from rigkit.capture.actions import file_frame, staged_frame
from rigkit.capture.checks import UNCHECKED, check_exif
from rigkit.capture.model import FIELD_STEPS, POSITIONS, Frame, Session
from rigkit.capture.views import (
    CheckFrame,
    ViewMap,
    admit,
    check_frame,
    decoded_with_full,
    full_image,
    kept,
    map_views,
    reference,
    view_map,
)
from rigkit.core.tables import visible
from rigkit.core.threads import ViewPool
from rigkit.errors import RigkitError
from rigkit.pipeline.checks import (
    MAX_RIGHT_SCALE_CHANGE,
    NO_MAGNIFICATION_SIGMAS,
    implied_range_m,
    roles_problem,
)
from rigkit.pipeline.shimmer import Shimmer, ShimmerStart, shimmer_from, shimmer_start
from rigkit.rig.bursts import burst_advice
from rigkit.rig.findings import Finding
from rigkit.rig.profile import RigProfile

MAX_BURST_SCALE_CHANGE = 0.002
"""The frames of one position's burst are one view: a scale change beyond this (the
back position's magnification is 1 - C_lb / z, 0.007 at 300 m) is another position."""
MAX_ROLL_DEG = 10.0
"""Largest plausible roll between two positions; more means a camera turned on its side."""
MAX_BLOWN = 0.01
"""Largest share of clipped pixels (:data:`rigkit.imagefile.picture.CLIP_LEVEL`) before the
highlights count as blown and the frame should be taken again."""
RANGE_FACTOR = 2.0
"""An implied range more than this factor from the profile's nominal range is suspect."""


# -- one place that knows how many frames a position holds -------------------------------


def frames_at(session: Session, position: str) -> tuple[Frame, ...]:
    """The frames recorded for ``position``, oldest first (empty if none yet)."""
    return session.bursts.get(position, ())


class Misfit(str):
    """Why a frame is none of a burst (:func:`burst_misfit`), one line; ``elsewhere``:
    it shows the scene from another position (else it matches nothing of it: another
    scene, a blank or blurred frame), which decides what it may be offered for."""

    elsewhere: bool

    def __new__(cls, reason: str, elsewhere: bool) -> Misfit:
        misfit = super().__new__(cls, reason)
        misfit.elsewhere = elsewhere
        return misfit


@dataclass(frozen=True)
class Ingested:
    """What :func:`ingest` did: ``session`` as saved with the frame (as it was where the
    frame is held back), and ``held``, why the frame was held back instead (None: it
    was added)."""

    session: Session
    held: Misfit | None = None


def ingest(session: Session, position: str, path: Path, *, replace_existing: bool = False,
           burst: bool = False, check_burst: bool = False) -> Ingested:
    """Add the frame at ``path`` to ``position`` (as one more of its burst with ``burst``,
    or replacing its frames with ``replace_existing``): staged, hashed and decoded once
    (:func:`rigkit.capture.actions.staged_frame`), its check image kept for the checks
    that follow (:func:`rigkit.capture.views.admit`), and, with ``check_burst``, held
    back rather than added where it is none of the position's burst
    (:func:`burst_misfit`). RigkitError where the frame is refused."""
    with staged_frame(session, position, path, replace_existing=replace_existing,
                      burst=burst) as staged:
        joins = burst and not replace_existing and bool(frames_at(staged.session, position))
        checked = admit(staged.sha256, staged.grey, staged.raw, keep_full=joins)
        misfit = burst_misfit(staged.session, position, path.name, checked) \
            if check_burst else None
        if misfit is not None:
            return Ingested(staged.session, misfit)
        return Ingested(file_frame(staged))


def burst_misfit(session: Session, position: str, name: str, new: CheckFrame
                 ) -> Misfit | None:
    """Why the frame called ``name`` (``new``: its check image) does not belong to
    ``position``'s burst, or None: the frames of a burst show one view, shifted a little
    by the tripod's sway, while a frame from another position shows the scene with
    parallax (the right one) or magnified (the back one), and a frame of another scene
    does not match at all. None too for the first frame of a position."""
    frames = frames_at(session, position)
    if not frames:
        return None
    try:
        first = check_frame(session, frames[0])
    except RigkitError:  # the burst's own first frame is said by its checks
        return None
    try:  # a frame that cannot be matched with the burst's is none of it
        view = map_views(first.image, new.image, first.reduction, session.rig().focal_px,
                         reference(session, frames[0]), axis="z" if position == "back" else "x")
    except RigkitError:
        return Misfit(f"{name} does not match the {position} burst (too little in common "
                      "with its first frame): another scene, or a blank or blurred frame?",
                      elsewhere=False)
    moved = view.parallax is not None and view.parallax.moved
    if not moved and abs(view.scale - 1.0) <= MAX_BURST_SCALE_CHANGE:
        return None
    parallax = "" if view.parallax is None else f"parallax {view.parallax.spread_px:.1f} px, "
    return Misfit(f"{name} does not match the {position} burst ({parallax}scale "
                  f"{view.scale:.4f}): it looks taken from another position", elsewhere=True)


def add_position_frame(session: Session, position: str, path: Path,
                       retake: bool | None = None) -> Session:
    """Record ``path`` as a frame of ``position`` (copied into ``raw/``, never moved): its
    first, one more of its burst, or the retake that replaces the position's frames
    (their files stay in ``raw/``): when ``retake`` says so or, left None, when the
    position's newest frame failed its on-site checks."""
    if retake is None:
        retake = newest_failed(session, position)
    return ingest(session, position, path, replace_existing=retake, burst=not retake).session


def newest_failed(session: Session, position: str) -> bool:
    """Whether ``position``'s newest frame failed its on-site checks: the next frame is
    then its retake, and never compared with it as a burst (a failed frame is nobody's
    reference)."""
    return bool(frames_at(session, position)) and not all_ok(onsite_checks(session, position))


def resume_step(session: Session) -> str:
    """The step ``rigkit field`` opens ``session`` at: the one it was on when it stopped
    (``session.field_step``), unless that needs frames the session lacks (then the first
    position without one, :func:`next_step`); where no step was recorded, the rig while no
    frame is taken, else :func:`next_step`; where the step recorded is none this rigkit
    knows (empty, or a newer rigkit's), :func:`next_step` (:func:`resume_note` says so)."""
    derived = next_step(session)
    step = session.field_step
    if step is None:
        return "rig" if derived == "left" else derived
    if step not in FIELD_STEPS or (step in ("targets", "process") and derived in POSITIONS):
        return derived
    return step


def resume_note(session: Session) -> str:
    """Why ``rigkit field`` does not open the step ``session.yaml`` records, where that
    is none it knows; "" otherwise."""
    step = session.field_step
    if step is None or step in FIELD_STEPS:
        return ""
    what = "is empty" if not step.strip() else \
        f"'{visible(step, lines=False)}' is no step this rigkit knows"
    return (f"{session.yaml_path}: field_step {what} ({', '.join(FIELD_STEPS)}); starting at "
            f"{resume_step(session)}, where the capture stands")


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


def _newest_for_checks(session: Session, position: str) -> np.ndarray | None:
    """Decodes ``position``'s newest frame for its checks (:func:`check_frame`) and
    returns it at full resolution where its shimmer against the burst's first frame is
    still to be measured (:func:`shimmer_check`), else None: one decoding for both."""
    frames = frames_at(session, position)
    newest = frames[-1]
    if len(frames) > 1 and (frames[0].sha256, newest.sha256) not in _MEASURED:
        return decoded_with_full(session, newest)
    check_frame(session, newest)
    return None


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
        note = view.parallax.little_relief()
        checks.insert(0, Finding("parallax", problem[0], redo=problem[1]) if problem else
                      Finding("parallax", note or f"parallax {view.parallax.spread_px:.1f} px "
                              "across the scene", ok=True))
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
    if abs(view.scale - 1.0) <= MAX_BURST_SCALE_CHANGE:  # the right view, or the left again
        checks.append(Finding(
            "magnification", f"back view {view.scale:.4f}×, the left view's size: taken beside "
            "the left position, not behind it (the right frame again?)",
            redo=f"take the back frame from {metres(c_lb)} straight behind the LEFT position",
        ))
        return checks
    if view.scale >= 1.0 or 1.0 - view.scale <= NO_MAGNIFICATION_SIGMAS * view.scale_sigma:
        checks.append(Finding(
            "magnification", f"back view {view.scale:.4f}×: not smaller than the left view"
            + ("" if view.scale >= 1.0 else
               f" by more than its noise (±{view.scale_sigma:.4f})"),
            redo=f"take the back frame {metres(c_lb)} behind the left position, same zoom",
        ))
        return checks
    z = implied_range_m(view.scale, c_lb)
    text = f"back view {view.scale:.4f}× → ~{_round_range(z)} m at C_lb = {metres(c_lb)}"
    nominal = profile.nominal_range_m
    if nominal is not None and not nominal / RANGE_FACTOR <= z <= nominal * RANGE_FACTOR:
        checks.append(Finding(
            "magnification", f"{text}, far from the planned {nominal:g} m",
            redo=f"check that the back position is {metres(c_lb)} behind the left one and the "
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


def metres(length_m: float) -> str:
    """A taped length as the profile gives it, to the millimetre without trailing zeros:
    "2.03 m", "2 m", "1.995 m" (never 2.03 shown as "2.0")."""
    return f"{length_m:.3f}".rstrip("0").rstrip(".") + " m"


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
        start = kept(_STARTS, first.sha256,
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
        except RigkitError:
            return [*checks, Finding("match", f"the {position} frame does not match the left "
                                     "one (too little in common to align them): another "
                                     "scene, or a blank or blurred frame?",
                                     redo=f"aim at the left frame's scene and take the "
                                     f"{position} frame")]
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


NEXT_FIRST = ("roles", "match", "magnification", "scale", "parallax", "rotation", "exposure",
              "exif")
"""Failed checks by what to redo first: a frame taken at the wrong position or of
another scene before its settings, whose fix would be lost with the frame."""


def next_move(checks: Sequence[Finding]) -> str | None:
    """The one thing to do next after ``checks`` (a frame's on-site checks): the redo
    of the failure that comes first in :data:`NEXT_FIRST`, None where none failed. The
    position screen shows it above the checks; ``n`` past a failure names it."""
    failed = [c for c in checks if not c.ok]
    if not failed:
        return None
    order = {code: i for i, code in enumerate(NEXT_FIRST)}
    first = min(failed, key=lambda c: order.get(c.code, len(order)))
    return first.redo or first.message
