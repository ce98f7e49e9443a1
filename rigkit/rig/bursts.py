"""How far the disparity offset may be off, from the heat shimmer and the burst length;
and the burst to take against the shimmer measured at the tripod.

The offset q is what the back camera fixes (paper Sec. 3, ambiguity removal). Its error
was measured on rendered scenes: a floor from the views' principal points, and a share
that grows with the shimmer and its correlation length and falls as 1/sqrt(frames) with
bursts (docs/pipeline.md, "Field conditions"; docs/rig-profiles.md).
"""

from __future__ import annotations

import math

from rigkit.errors import InputError
from rigkit.pipeline.estimate import OFFSET_WARNING_FRACTION
from rigkit.pipeline.shimmer import Shimmer
from rigkit.rig.defaults import SHIMMER_PX
from rigkit.rig.formulas import disparity_px
from rigkit.rig.profile import RigProfile

REFERENCE_SIZE = (4608, 3456)
"""The image size at which the measured figures below hold (scaled by the diagonal)."""
OFFSET_FLOOR_PX = 0.37
"""Error of the global disparity offset without heat shimmer, px at REFERENCE_SIZE:
what the views' principal points (up to ±30 px each in those scenes) leave: 0.37 px
RMS over 20 ideal scenes (docs/results-log.md; 0.35 px since the lens fit's
cluster-robust sigma, which this keeps as the rounder, larger figure)."""
OFFSET_PER_SHIMMER_PX = 2.8
"""Offset error per px RMS of heat shimmer in one frame per position: on 20 field
scenes at 0.3 px the offset was off by 0.92 px RMS (0.90 px since), 0.84 px of it
beyond the floor.
Shimmer moves ~50 px patches together, so matching more points does not lower it;
only more frames do, by ~1/sqrt(frames) (docs/pipeline.md, "Field conditions")."""
SHIMMER_CORR = 0.01
"""Correlation length of the shimmer ``OFFSET_PER_SHIMMER_PX`` was measured under, as a
fraction of the image width (46 px at 4608; the Gaussian sigma of
:mod:`rigkit.pipeline.shimmer`)."""
REFERENCE_FOCAL_PX = 43962.93892852579
"""The focal length the figures above were measured at, px: 6 deg across 4608 px."""
SHIMMER_RAD = SHIMMER_PX / REFERENCE_FOCAL_PX
SHIMMER_CORR_RAD = SHIMMER_CORR * REFERENCE_SIZE[0] / REFERENCE_FOCAL_PX
"""``SHIMMER_PX`` and its correlation length as the angles they are (6.8 µrad RMS over
patches of 1.05 mrad): the air does not know the camera's pixels."""
MAX_FRAMES = 64
"""The longest burst per position :func:`frames_for_offset` proposes."""
NINE_IN_TEN = 1.645
"""A normal error stays within this many standard deviations nine times in ten."""


def default_shimmer(focal_px: float) -> tuple[float, float]:
    """(RMS per axis, correlation length), px, of moderate heat shimmer over 300 m seen
    at a focal length of ``focal_px``: ``SHIMMER_RAD`` and ``SHIMMER_CORR_RAD`` in that
    camera's pixels (0.3 px over 46 px at the synthetic protocol's 43,963 px; 0.36 px
    for the P1000 at 400 mm-eq.; 0.1 px for a 1536 px frame of the same 6 deg view)."""
    return SHIMMER_RAD * focal_px, SHIMMER_CORR_RAD * focal_px


def expected_offset_error_px(
    image_size: tuple[int, int],
    frames: int = 1,
    shimmer_px: float = SHIMMER_PX,
    shimmer_corr_px: float | None = None,
) -> float:
    """Expected error of the global disparity offset, px at ``image_size``, for bursts
    of ``frames`` per position under ``shimmer_px`` RMS of heat shimmer (px at that
    size) correlated over ``shimmer_corr_px`` (None: ``SHIMMER_CORR`` of the width, as
    measured): the floor without shimmer and the shimmer's share, root-sum-square.
    The share grows with the correlation length, as the number of independent patches
    on the surface falls with its square (docs/rig-profiles.md)."""
    if frames < 1:
        raise InputError(f"frames per position must be >= 1, got {frames}")
    if not shimmer_px >= 0:
        raise InputError(f"shimmer must be >= 0 px, got {shimmer_px:g}")
    patch_ratio = 1.0  # the shimmer's patches against those it was measured under
    if shimmer_corr_px is not None:
        if not shimmer_corr_px > 0:
            raise InputError(f"shimmer correlation must be > 0 px, got {shimmer_corr_px:g}")
        patch_ratio = shimmer_corr_px / (SHIMMER_CORR * image_size[0])
    shimmer = OFFSET_PER_SHIMMER_PX * shimmer_px * patch_ratio / math.sqrt(frames)
    return math.hypot(OFFSET_FLOOR_PX * reference_scale(image_size), shimmer)


def frames_for_offset(
    image_size: tuple[int, int],
    disparity_px: float,
    shimmer_px: float,
    shimmer_corr_px: float | None = None,
) -> int | None:
    """The fewest frames per position whose expected offset error
    (:func:`expected_offset_error_px`, taken as normal) keeps the median depth within
    ``OFFSET_WARNING_FRACTION`` of the truth in nine captures out of ten, at a
    disparity of ``disparity_px`` (f C_lr / z). None where no burst of up to
    ``MAX_FRAMES`` does (the floor without shimmer is above it: a farther scene than
    the rig is for)."""
    limit = OFFSET_WARNING_FRACTION * disparity_px / NINE_IN_TEN
    for frames in range(1, MAX_FRAMES + 1):
        if expected_offset_error_px(image_size, frames, shimmer_px, shimmer_corr_px) <= limit:
            return frames
    return None


def burst_advice(profile: RigProfile, shimmer: Shimmer, where: str, range_m: float
                 ) -> tuple[str, int | None]:
    """One line on the ``shimmer`` measured from ``where`` (e.g. "left frames 1 and 2")
    and the burst it calls for at ``range_m`` with the rig of ``profile`` (its focal
    length, C_lr and image size): (the line, :func:`frames_for_offset`'s answer). The
    one computation of the burst to take, on site (at the planned range) and after
    processing (at the measured median depth). The burst comes from the figures as the
    line shows them (the RMS to 0.01 px, the correlation length to two figures, the
    range to the metre), so one shown measurement always gets one answer: 0.0849 and
    0.0751 px, both "0.08 px", once gave 2 frames and then 1."""
    rms, range_m = round(shimmer.rms_px, 2), float(round(range_m))
    corr = float(f"{shimmer.corr_px:.2g}") if math.isfinite(shimmer.corr_px) else None
    patches = "" if corr is None else f" in patches of ~{corr:g} px"
    text = f"heat shimmer {rms:.2f} px RMS{patches} ({where})"
    disparity = disparity_px(range_m, profile.focal_px, profile.baseline_lr.value_m)
    need = frames_for_offset(profile.image_size, disparity, rms, corr)
    bar = f"{100 * OFFSET_WARNING_FRACTION:g} % of depth"
    if need is None:
        return f"{text}; at {range_m:.0f} m no burst keeps the offset within {bar}", None
    frames = "1 frame" if need == 1 else f"{need} frames"
    return (f"{text}: take {frames} per position to keep the offset within {bar} at "
            f"{range_m:.0f} m (9 times in 10)"), need


def burst_warning(profile: RigProfile, shimmer: Shimmer, where: str, depth_m: float,
                  frames: int) -> str | None:
    """For a processed capture of ``frames`` per position whose median depth is
    ``depth_m``: the :func:`burst_advice` line where its burst is shorter than the
    measured ``shimmer`` calls for, else None (also where there is no depth)."""
    if not depth_m > 0:
        return None
    text, need = burst_advice(profile, shimmer, where, depth_m)
    if need is not None and need <= frames:
        return None
    return f"{text}; this capture has {frames}"


def reference_scale(image_size: tuple[int, int]) -> float:
    """A figure in px measured at ``REFERENCE_SIZE`` scaled to ``image_size``: the ratio
    of the image diagonals."""
    return math.hypot(*image_size) / math.hypot(*REFERENCE_SIZE)
