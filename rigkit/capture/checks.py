"""The capture check: the three frames' EXIF against each other and the rig profile.

One camera (or three) must shoot the left, right and back frames with the same focal
length and exposure; each frame's focal length must match its camera's within the
profile's tolerance. A different focal length breaks the one-f assumption the depth
scale rests on, so processing stops on it (:func:`capture_warnings`, unless forced);
everything else is a warning. The image size is not taken from EXIF, which often
describes a preview: the decoded frame's size is checked against the rig
(:func:`rigkit.imagefile.imagesize.check_size`).
"""

from __future__ import annotations

import math
import re
from collections.abc import Mapping, Sequence
from datetime import datetime
from pathlib import Path

from rigkit.capture.model import POSITIONS
from rigkit.errors import InputError
from rigkit.imagefile.exif import ExifInfo, read_exif
from rigkit.imagefile.rawio import frame_size
from rigkit.rig.findings import Finding
from rigkit.rig.optics import focal_px_from_35mm_equivalent, focal_px_from_mm
from rigkit.rig.profile import CAMERA_ROLES, CameraSpec, RigProfile

EXIF_MM_STEP = 0.1
"""EXIF FocalLength is usually recorded to 0.1 mm; FocalLengthIn35mmFilm to whole mm."""
MAX_CAPTURE_SPAN_S = 30 * 60.0
"""Longest plausible time between the first and last frame of one capture, seconds."""

#: Finding codes from the capture check that stop processing (``force`` overrides): a
#: different focal length breaks the one-f assumption the depth scale rests on.
FATAL_FINDINGS = frozenset({"capture.focal_vs_profile"})
FATAL_MISMATCH_FIELDS = frozenset({"FocalLength", "FocalLengthIn35mmFilm"})
UNCHECKED = frozenset({"capture.no_exif", "capture.focal_unchecked"})
"""Capture findings that say something was not recorded, not that it is wrong."""


_CONSISTENT_FIELDS = (
    ("focal_length_mm", "FocalLength"),
    ("focal_length_35mm_mm", "FocalLengthIn35mmFilm"),
    ("exposure_time_s", "ExposureTime"),
    ("f_number", "FNumber"),
    ("iso", "ISOSpeedRatings"),
)


def check_capture(profile: RigProfile, paths: Sequence[str | Path]) -> list[Finding]:
    """Check the left, right and back frames' EXIF against each other and the profile.

    The three frames must share focal length and exposure (time, aperture, ISO); each
    frame's focal length must match its camera's within the profile's tolerance.
    Returns one Finding per problem (empty: all good); InputError if there are not
    three paths or a file cannot be read.
    """
    if len(paths) != len(CAMERA_ROLES):
        raise InputError(f"a capture is three images (left, right, back), got {len(paths)}")
    return check_exif(profile, dict(zip(CAMERA_ROLES, paths, strict=True)))


def size_findings(profile: RigProfile, paths: Sequence[str | Path]) -> list[Finding]:
    """A finding for each of the left, right and back frames whose decoded size
    (:func:`rigkit.imagefile.rawio.frame_size`, not an EXIF size) is not the profile's."""
    expected = profile.image_size
    found = []
    for role, path in zip(CAMERA_ROLES, paths, strict=True):
        width, height = frame_size(path)
        if (width, height) != expected:
            turned = " (turned to portrait?)" if (height, width) == expected else ""
            found.append(Finding(
                "capture.size_vs_profile",
                f"{role} frame ({Path(path).name}): decoded image {width}x{height} px differs "
                f"from the profile's {expected[0]}x{expected[1]} px{turned}", role, "size"))
    return found


def check_exif(profile: RigProfile, paths: Mapping[str, str | Path]) -> list[Finding]:
    """:func:`check_capture`'s rules for the frames taken so far (role -> path, any of
    left, right and back), as the field TUI checks each frame as it arrives."""
    frames = {role: read_exif(path) for role, path in paths.items()}
    findings = [
        Finding("capture.no_exif", f"{_frame(role, info)}: no EXIF found; nothing checked", role)
        for role, info in frames.items()
        if not info.has_exif
    ]
    present = {role: info for role, info in frames.items() if info.has_exif}
    for attribute, tag in _CONSISTENT_FIELDS:
        findings += _consistency(present, attribute, tag)
    for role, info in present.items():
        findings += _against_profile(role, info, profile.cameras[role])
    findings += _time_findings(present)
    return findings


def _time_findings(frames: dict[str, ExifInfo]) -> list[Finding]:
    """A finding when the frames' capture times are unreadable or spread too far apart.

    One camera moved between three tripod positions takes minutes; beyond
    MAX_CAPTURE_SPAN_S the light, shadows or the scene itself may have changed.
    """
    times: dict[str, datetime] = {}
    found = []
    for role, info in frames.items():
        if info.datetime_original is None:
            continue
        try:
            times[role] = datetime.strptime(info.datetime_original, "%Y:%m:%d %H:%M:%S")
        except ValueError:
            message = f"{_frame(role, info)}: unreadable DateTimeOriginal " \
                f"{info.datetime_original!r}"
            found.append(Finding("capture.bad_time", message, role, "DateTimeOriginal"))
    if len(times) >= 2:
        first, last = min(times.values()), max(times.values())
        span = (last - first).total_seconds()
        if span > MAX_CAPTURE_SPAN_S:
            order = ", ".join(f"{role} {t:%H:%M:%S}" for role, t in times.items())
            message = (
                f"frames taken {span / 60:.0f} min apart ({order}); over "
                f"{MAX_CAPTURE_SPAN_S / 60:.0f} min the light or the scene may have changed"
            )
            found.append(Finding("capture.time_spread", message, None, "DateTimeOriginal"))
    return found


def _frame(role: str, info: ExifInfo) -> str:
    return f"{role} frame ({info.path.name})"


def _consistency(frames: dict[str, ExifInfo], attribute: str, tag: str) -> list[Finding]:
    """Findings where frames disagree on one EXIF field, or only some record it."""
    values = {role: getattr(info, attribute) for role, info in frames.items()}
    known = {role: value for role, value in values.items() if value is not None}
    if not known:
        return []
    reference_role, reference = next(iter(known.items()))
    shown = _format_field(tag, reference)
    found = []
    for role, value in values.items():
        if value is None:
            message = (
                f"{_frame(role, frames[role])}: no {tag} in EXIF, {reference_role} has {shown}"
            )
            found.append(Finding("capture.missing_field", message, role, tag))
        elif not math.isclose(value, reference, rel_tol=1e-6):
            message = (
                f"{_frame(role, frames[role])}: {tag} {_format_field(tag, value)} differs "
                f"from the {reference_role} frame's {shown}"
            )
            found.append(Finding("capture.mismatch", message, role, tag))
    return found


def _format_field(tag: str, value: float) -> str:
    if tag == "ExposureTime":
        return f"1/{1 / value:.4g} s" if value < 1 else f"{value:g} s"
    if tag == "FNumber":
        return f"f/{value:g}"
    if tag == "ISOSpeedRatings":
        return f"ISO {value:g}"
    return f"{value:g} mm"


def _against_profile(role: str, info: ExifInfo, camera: CameraSpec) -> list[Finding]:
    return [
        finding
        for finding in (
            _focal_finding(role, info, camera),
            _model_finding(role, info, camera),
        )
        if finding is not None
    ]


def exif_focal_px(info: ExifInfo, camera: CameraSpec) -> tuple[str, float, float] | None:
    """A frame's focal length in pixels from EXIF, or None if no usable field.

    Returns (EXIF tag used, pixels, EXIF rounding as a fraction). The tag is the one
    matching how the profile states its focal length (35 mm-equivalent or real mm),
    so both sides go through the same conversion; real mm needs ``sensor_mm``.
    """
    mm = None
    if info.focal_length_mm is not None and camera.sensor_mm is not None:
        pixels = focal_px_from_mm(info.focal_length_mm, camera.sensor_mm[0], camera.resolution[0])
        mm = ("FocalLength", pixels, EXIF_MM_STEP / 2 / info.focal_length_mm)
    equivalent = None
    if info.focal_length_35mm_mm is not None:
        pixels = focal_px_from_35mm_equivalent(
            info.focal_length_35mm_mm, camera.sensor_mm, camera.resolution
        )
        equivalent = ("FocalLengthIn35mmFilm", pixels, 0.5 / info.focal_length_35mm_mm)
    given_as_equivalent = camera.focal_given is not None and camera.focal_given[0].startswith(
        "equivalent"
    )
    preferred = (equivalent, mm) if given_as_equivalent else (mm, equivalent)
    return next((choice for choice in preferred if choice is not None), None)


def _focal_finding(role: str, info: ExifInfo, camera: CameraSpec) -> Finding | None:
    measured = exif_focal_px(info, camera)
    if measured is None:
        why = "the profile has no sensor_mm" if info.focal_length_mm else "EXIF has none"
        message = f"{_frame(role, info)}: focal length not checked ({why})"
        return Finding("capture.focal_unchecked", message, role, "FocalLength")
    tag, pixels, rounding = measured
    off = pixels / camera.focal_px - 1.0
    allowed = camera.focal_tolerance + rounding
    if abs(off) <= allowed:
        return None
    recorded = info.focal_length_35mm_mm if tag == "FocalLengthIn35mmFilm" else info.focal_length_mm
    message = (
        f"{_frame(role, info)}: {tag} {recorded:g} mm is {pixels:,.0f} px, "
        f"{100 * off:+.1f} % off the profile's {camera.focal_px:,.0f} px "
        f"(tolerance {100 * camera.focal_tolerance:g} %)"
    )
    return Finding("capture.focal_vs_profile", message, role, tag)


def _model_finding(role: str, info: ExifInfo, camera: CameraSpec) -> Finding | None:
    if info.model is None:
        return None
    recorded, expected = _words(info.model), _words(camera.model)
    if recorded <= expected or expected <= recorded:
        return None
    message = (
        f"{_frame(role, info)}: camera model {info.model!r} is not the profile's {camera.model!r}"
    )
    return Finding("capture.model_vs_profile", message, role, "Model")


def _words(text: str) -> set[str]:
    """Lower-case words and numbers: 'COOLPIX P1000' -> {'coolpix', 'p1000'}."""
    return set(re.findall(r"[a-z0-9]+", text.lower()))


def capture_warnings(profile: RigProfile, paths: Mapping[str, Path], force: bool
                     ) -> tuple[str, ...]:
    """The left, right and back frames' (role -> path) capture findings as one-line
    warnings; InputError for a fatal one (a focal length that contradicts the rig, or
    differs between the frames) unless ``force``. What could not be checked (no EXIF,
    no sensor size in the profile) is one line, not one per frame."""
    findings = check_exif(profile, paths)
    fatal = [
        f for f in findings
        if f.code in FATAL_FINDINGS
        or (f.code == "capture.mismatch" and f.field in FATAL_MISMATCH_FIELDS)
    ]
    if fatal and not force:
        raise InputError("; ".join(f.message for f in fatal) + " (--force processes it anyway)")
    warnings = tuple(f.message for f in findings if f.code not in UNCHECKED)
    unchecked = [f for f in findings if f.code in UNCHECKED]
    if [f.code for f in unchecked] == ["capture.no_exif"] * len(POSITIONS):
        return (*warnings, "no EXIF in any frame (e.g. rendered images): capture settings "
                "not checked")
    if unchecked:
        return (*warnings, "not checked: " + "; ".join(
            f.message.split(": ", 1)[-1] for f in unchecked))
    return warnings
