"""The rig geometry check: error budget and geometry warnings (the capture (EXIF) check
is :mod:`rigkit.capture.checks`).

Notation (paper, Sec. 2-3): z depth in metres, f focal length in pixels, C_lr the
left-right baseline and C_lb the left-back distance along the viewing axis, in metres.

Error budget, each source alone, to first order (|dz| in metres):

* disparity d = f * C_lr / z (pixels)
* a disparity error dd (pixels):             dz = z**2 * dd / (f * C_lr)
* a relative error e in f, C_lr or C_lb:     dz = z * e
* an error dq in the global disparity offset: dz = z**2 * dq / (f * C_lr), with dq
  measured on rendered scenes as a function of heat shimmer and burst length
  (:func:`expected_offset_error_px`)
* a lens distortion error that moves the image corner by dc (pixels): where a
  rotation g between cameras moves the image by s = f tan(g), a radial error growing
  as r**3 changes by up to 3 dc s / r_c between the two positions of a point: a
  disparity error dd = 3 dc s / r_c (r_c: the corner's distance from the centre, px)

The offset q is what the back camera fixes (paper Sec. 3, ambiguity removal); C_lb
enters through the anchor depth z = C_lb / (m_l / m_b - 1), so its relative error
carries over to z. The sources are independent, so the total is their root-sum-square.
This is the plain-stereo view: where the back camera's anchor lies at the same depth,
errors in f and C_lr cancel there (docs/rig-profiles.md, "Reading the error budget").
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np

from rigkit.errors import InputError
from rigkit.geometry import distort
from rigkit.pipeline.estimate import OFFSET_WARNING_FRACTION
from rigkit.pipeline.settings import PipelineSettings
from rigkit.pipeline.shimmer import Shimmer
from rigkit.rig.optics import fov_deg
from rigkit.rig.profile import Baseline, RigProfile, rig_to_dict

DISPARITY_ERROR_PX = PipelineSettings().stereo_noise_px
"""Default disparity (matching) error, pixels: the pipeline's own figure."""
REFERENCE_SIZE = (4608, 3456)
"""The image size at which the measured figures below hold (scaled by the diagonal)."""
OFFSET_FLOOR_PX = 0.37
"""Error of the global disparity offset without heat shimmer, px at REFERENCE_SIZE:
what the views' principal points (up to ±30 px each in those scenes) leave: 0.37 px
RMS over 20 ideal scenes (docs/results.md; 0.35 px since the lens fit's
cluster-robust sigma, which this keeps as the rounder, larger figure)."""
OFFSET_PER_SHIMMER_PX = 2.8
"""Offset error per px RMS of heat shimmer in one frame per position: on 20 field
scenes at 0.3 px the offset was off by 0.92 px RMS (0.90 px since), 0.84 px of it
beyond the floor.
Shimmer moves ~50 px patches together, so matching more points does not lower it;
only more frames do, by ~1/sqrt(frames) (docs/pipeline.md, "Field conditions")."""
SHIMMER_PX = 0.3
"""Default heat shimmer, px RMS per frame: moderate turbulence over 300 m at ~19 urad
per pixel (docs/field.md)."""
SHIMMER_CORR = 0.01
"""Correlation length of the shimmer ``OFFSET_PER_SHIMMER_PX`` was measured under, as a
fraction of the image width (46 px at 4608; the Gaussian sigma of
:mod:`rigkit.pipeline.shimmer`)."""
MAX_FRAMES = 64
"""The longest burst per position :func:`frames_for_offset` proposes."""
NINE_IN_TEN = 1.645
"""A normal error stays within this many standard deviations nine times in ten."""
BUDGET_RANGES_M = (100.0, 150.0, 200.0, 250.0, 300.0, 350.0, 400.0, 450.0, 500.0)
TARGET_FRACTIONS = (0.01, 0.03)
"""Relative depth errors whose onset range the check reports (1 % and 3 %)."""
RELATIVE_ROTATION_DEG = 1.0
"""Rotation between cameras assumed for the affine residual (paper: up to 1 deg about x, y)."""
LENS_FIT_CORNER_PX = 0.5
"""Error at the image corner of the distortion the pipeline fits from the views, px at
REFERENCE_SIZE (field scenes with 0.3 px shimmer, docs/results.md; scaled by the image
size for other sizes)."""

STEREO_LIMIT = 0.01
"""Warn when the disparity error alone exceeds this fraction of the depth."""
ANCHOR_LIMIT = 0.10
"""Warn when one pair of back-camera matches fixes the depth only to worse than this."""
AFFINE_LIMIT = 0.01
"""Warn when the non-affine residual exceeds this fraction of the disparity."""
OVERLAP_LIMIT = 0.5
"""Warn when the left and right views overlap by less than this fraction of the width."""


# --------------------------------------------------------------------------- formulas


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
    return math.hypot(OFFSET_FLOOR_PX * _reference_scale(image_size), shimmer)


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


def burst_advice(
    shimmer: Shimmer, where: str, image_size: tuple[int, int], disparity_px: float,
    range_m: float,
) -> tuple[str, int | None]:
    """One line on the ``shimmer`` measured from ``where`` (e.g. "left frames 1 and 2")
    and the burst it calls for at ``range_m`` (disparity ``disparity_px`` there, images
    of ``image_size``): (the line, :func:`frames_for_offset`'s answer)."""
    text = f"heat shimmer {shimmer.rms_px:.2f} px RMS ({where})"
    corr = shimmer.corr_px if math.isfinite(shimmer.corr_px) else None
    need = frames_for_offset(image_size, disparity_px, shimmer.rms_px, corr)
    bar = f"{100 * OFFSET_WARNING_FRACTION:g} % of depth"
    if need is None:
        return f"{text}; at {range_m:.0f} m no burst keeps the offset within {bar}", None
    return (f"{text}: take {need} frames per position to keep the offset within {bar} at "
            f"{range_m:.0f} m (9 times in 10)"), need


def burst_warning(
    shimmer: Shimmer, where: str, image_size: tuple[int, int], focal_px: float,
    baseline_lr_m: float, depth_m: float, frames: int,
) -> str | None:
    """For a processed capture of ``frames`` per position whose median depth is
    ``depth_m``: the :func:`burst_advice` line where its burst is shorter than the
    measured ``shimmer`` calls for, else None (also where there is no depth)."""
    if not depth_m > 0:
        return None
    disparity = disparity_px(depth_m, focal_px, baseline_lr_m)
    text, need = burst_advice(shimmer, where, image_size, disparity, depth_m)
    if need is not None and need <= frames:
        return None
    return f"{text}; this capture has {frames}"


def _reference_scale(image_size: tuple[int, int]) -> float:
    """A figure in px measured at ``REFERENCE_SIZE`` scaled to ``image_size``: the ratio
    of the image diagonals."""
    return math.hypot(*image_size) / math.hypot(*REFERENCE_SIZE)


def disparity_px(range_m: float, focal_px: float, baseline_m: float) -> float:
    """Disparity d = f * C / z in pixels (paper Sec. 3, depth-to-disparity formula)."""
    return focal_px * baseline_m / range_m


def triangulation_angle_deg(range_m: float, baseline_m: float) -> float:
    """Angle in degrees between the two rays to a point on the left camera's axis at ``range_m``."""
    return math.degrees(math.atan2(baseline_m, range_m))


def depth_error_from_disparity(
    range_m: float, focal_px: float, baseline_m: float, disparity_error_px: float
) -> float:
    """Depth error in metres from a disparity error: z**2 * dd / (f * C_lr).

    Also the depth error from an error of the global disparity offset.
    """
    return range_m**2 * disparity_error_px / (focal_px * baseline_m)


def depth_error_from_relative(range_m: float, relative_error: float) -> float:
    """Depth error in metres from a relative error of f, C_lr or C_lb: z * e."""
    return range_m * relative_error


def back_shift_px(range_m: float, baseline_lb_m: float, span_px: float) -> float:
    """How much shorter a ``span_px`` distance in the left view is in the back view, pixels.

    m_l - m_b = m_l * C_lb / (z + C_lb) for two points at depth z (paper Prop. 2).
    """
    return span_px * baseline_lb_m / (range_m + baseline_lb_m)


def anchor_error_fraction(
    range_m: float, baseline_lb_m: float, span_px: float, match_error_px: float
) -> float:
    """Relative depth error of one back-camera anchor, z = C_lb / (m_l / m_b - 1).

    For two left-view points ``span_px`` apart whose back-view matches are each off by
    ``match_error_px``: m_b is off by sqrt(2) * that, so dz / z = sqrt(2) * dm / (m_l - m_b).
    """
    return math.sqrt(2.0) * match_error_px / back_shift_px(range_m, baseline_lb_m, span_px)


def affine_residual_px(focal_px: float, image_size: tuple[int, int], rotation_deg: float) -> float:
    """Largest non-affine image shift, pixels, that a small rotation leaves at the corners.

    A rotation g about x maps u to u * cos(t) / cos(t - g) ~ u - g * u * v / f (proof of
    Prop. 1): a bilinear term, at the corners g * (w / 2) * (h / 2) / f.
    """
    width, height = image_size
    return math.radians(rotation_deg) * (width / 2.0) * (height / 2.0) / focal_px


def corner_distortion(profile: RigProfile) -> tuple[float, float]:
    """How far the profile's lens distortion moves the image corner: (radial scale
    change as a fraction, displacement in px), about the image centre. (0, 0) without
    distortion."""
    width, height = profile.image_size
    f = profile.focal_px
    x, y = (width - 1) / 2 / f, (height - 1) / 2 / f
    xd, yd = distort(np.array(x), np.array(y), profile.distortion)
    shift_px = float(np.hypot(xd - x, yd - y)) * f
    return shift_px / (math.hypot(x, y) * f), shift_px


def lens_corner_error_px(profile: RigProfile) -> float:
    """How far the lens model the pipeline will use may be off at the image corner, px:
    the self-calibration's error when it fits the lens from the views, otherwise the
    given profile's own misfit (lensfun's model converted; a calibrated lens: 0)."""
    if profile.pipeline_settings().distortion_terms:
        return LENS_FIT_CORNER_PX * _reference_scale(profile.image_size)
    spec = profile.cameras["left"]
    return spec.lens_profile.fit_error_px if spec.lens_profile else 0.0


def lens_disparity_error_px(
    corner_error_px: float, focal_px: float, image_size: tuple[int, int]
) -> float:
    """Disparity error from a distortion error of ``corner_error_px`` at the corner,
    for views turned by ``RELATIVE_ROTATION_DEG`` (module docstring)."""
    shift = focal_px * math.tan(math.radians(RELATIVE_ROTATION_DEG))
    return 3.0 * corner_error_px * shift / (math.hypot(*image_size) / 2.0)


@dataclass(frozen=True)
class ErrorModel:
    """The inputs of the error budget (pixels, fractions and Baseline in metres)."""

    focal_px: float
    focal_tolerance: float
    baseline_lr: Baseline
    baseline_lb: Baseline
    disparity_error_px: float = DISPARITY_ERROR_PX
    offset_error_px: float = OFFSET_FLOOR_PX
    lens_corner_px: float = 0.0
    lens_error_px: float = 0.0
    frames: int | None = None
    shimmer_px: float | None = None
    shimmer_corr_px: float | None = None
    """What ``offset_error_px`` was derived from (None: it was given; a None correlation
    length: the 1 % of the width it was measured at)."""

    @classmethod
    def from_profile(
        cls,
        profile: RigProfile,
        disparity_error_px: float = DISPARITY_ERROR_PX,
        offset_error_px: float | None = None,
        frames: int = 1,
        shimmer_px: float = SHIMMER_PX,
        shimmer_corr_px: float | None = None,
    ) -> ErrorModel:
        """The model for a profile (its focal length, tolerances, baselines and lens).
        The offset's error is ``offset_error_px`` where given, else what ``frames`` per
        position under ``shimmer_px`` of shimmer correlated over ``shimmer_corr_px``
        leave (:func:`expected_offset_error_px`)."""
        derived = offset_error_px is None
        if offset_error_px is None:
            offset_error_px = expected_offset_error_px(
                profile.image_size, frames, shimmer_px, shimmer_corr_px
            )
        corner = lens_corner_error_px(profile)
        return cls(
            focal_px=profile.focal_px,
            focal_tolerance=profile.focal_tolerance,
            baseline_lr=profile.baseline_lr,
            baseline_lb=profile.baseline_lb,
            disparity_error_px=disparity_error_px,
            offset_error_px=offset_error_px,
            lens_corner_px=corner,
            lens_error_px=lens_disparity_error_px(corner, profile.focal_px, profile.image_size),
            frames=frames if derived else None,
            shimmer_px=shimmer_px if derived else None,
            shimmer_corr_px=shimmer_corr_px if derived else None,
        )

    @property
    def quadratic_term(self) -> float:
        """a in total(z) = z * sqrt((a z)**2 + b**2): disparity, offset and lens errors, 1/m."""
        pixels = math.hypot(self.disparity_error_px, self.offset_error_px, self.lens_error_px)
        return pixels / (self.focal_px * self.baseline_lr.value_m)

    @property
    def constant_term(self) -> float:
        """b in total(z) = z * sqrt((a z)**2 + b**2): f, C_lr and C_lb tolerances."""
        return math.hypot(
            self.focal_tolerance,
            self.baseline_lr.relative_tolerance,
            self.baseline_lb.relative_tolerance,
        )


@dataclass(frozen=True)
class BudgetRow:
    """Depth errors at one range, metres, each source alone, and their root-sum-square."""

    range_m: float
    disparity_px: float
    from_disparity_m: float
    from_baseline_lr_m: float
    from_baseline_lb_m: float
    from_focal_m: float
    from_offset_m: float
    from_lens_m: float = 0.0

    @property
    def total_m(self) -> float:
        """Root-sum-square of the independent sources, metres."""
        return math.sqrt(
            self.from_disparity_m**2
            + self.from_baseline_lr_m**2
            + self.from_baseline_lb_m**2
            + self.from_focal_m**2
            + self.from_offset_m**2
            + self.from_lens_m**2
        )

    @property
    def total_fraction(self) -> float:
        """``total_m`` as a fraction of the range."""
        return self.total_m / self.range_m


def budget_row(model: ErrorModel, range_m: float) -> BudgetRow:
    """The error budget at one range."""
    lr = model.baseline_lr.value_m
    return BudgetRow(
        range_m=range_m,
        disparity_px=disparity_px(range_m, model.focal_px, lr),
        from_disparity_m=depth_error_from_disparity(
            range_m, model.focal_px, lr, model.disparity_error_px
        ),
        from_baseline_lr_m=depth_error_from_relative(range_m, model.baseline_lr.relative_tolerance),
        from_baseline_lb_m=depth_error_from_relative(range_m, model.baseline_lb.relative_tolerance),
        from_focal_m=depth_error_from_relative(range_m, model.focal_tolerance),
        from_offset_m=depth_error_from_disparity(
            range_m, model.focal_px, lr, model.offset_error_px
        ),
        from_lens_m=depth_error_from_disparity(range_m, model.focal_px, lr, model.lens_error_px),
    )


def range_reaching(model: ErrorModel, fraction: float) -> float | None:
    """The range in metres at which the total relative error reaches ``fraction``.

    total / z = sqrt((a z)**2 + b**2), so z = sqrt(fraction**2 - b**2) / a. Returns 0.0
    when the range-independent part b alone reaches it, None when it is never reached.
    """
    a, b = model.quadratic_term, model.constant_term
    if b >= fraction:
        return 0.0
    if a == 0.0:
        return None
    return math.sqrt(fraction**2 - b**2) / a


# --------------------------------------------------------------------------- geometry


@dataclass(frozen=True)
class RangeGeometry:
    """The rig's geometry at one range (lengths in m, angles in degrees, shifts in px)."""

    range_m: float
    disparity_px: float
    baseline_ratio_lr: float
    triangulation_angle_deg: float
    overlap_fraction: float
    back_scale_change: float
    back_shift_px: float
    anchor_error_fraction: float
    affine_residual_px: float

    @property
    def affine_error_fraction(self) -> float:
        """The affine residual as a fraction of the disparity (~ the depth error it causes)."""
        return self.affine_residual_px / self.disparity_px


def geometry_at(profile: RigProfile, range_m: float, match_error_px: float) -> RangeGeometry:
    """Geometry at ``range_m``; the back-camera anchor uses pairs half the image width apart."""
    focal = profile.focal_px
    width, height = profile.image_size
    lr, lb = profile.baseline_lr.value_m, profile.baseline_lb.value_m
    disparity = disparity_px(range_m, focal, lr)
    return RangeGeometry(
        range_m=range_m,
        disparity_px=disparity,
        baseline_ratio_lr=lr / range_m,
        triangulation_angle_deg=triangulation_angle_deg(range_m, lr),
        overlap_fraction=max(0.0, 1.0 - disparity / width),
        back_scale_change=lb / range_m,
        back_shift_px=back_shift_px(range_m, lb, width / 2.0),
        anchor_error_fraction=anchor_error_fraction(range_m, lb, width / 2.0, match_error_px),
        affine_residual_px=affine_residual_px(focal, (width, height), RELATIVE_ROTATION_DEG),
    )


@dataclass(frozen=True)
class Finding:
    """One warning: a stable ``code`` for machines, a one-line ``message`` for people.

    ``frame`` (left/right/back) and ``field`` (EXIF tag) are set for capture findings.
    """

    code: str
    message: str
    frame: str | None = None
    field: str | None = None


def geometry_warnings(
    profile: RigProfile, geometries: Sequence[RangeGeometry], model: ErrorModel
) -> list[Finding]:
    """Warnings where the geometry cannot deliver depth at the chosen ranges.

    Per range: too little left/right overlap, C_lr or C_lb too small. Once, at the
    farthest range (where it is worst): a field of view too wide for the affine model.
    """
    findings: list[Finding] = []
    for geometry in geometries:
        findings += _range_warnings(profile, geometry, model)
    if geometries:
        farthest = max(geometries, key=lambda geometry: geometry.range_m)
        if farthest.affine_error_fraction > AFFINE_LIMIT:
            findings.append(_fov_warning(profile, farthest, model))
    return findings


def _range_warnings(
    profile: RigProfile, geometry: RangeGeometry, model: ErrorModel
) -> list[Finding]:
    z = geometry.range_m
    lr, lb = profile.baseline_lr.value_m, profile.baseline_lb.value_m
    stereo = depth_error_from_disparity(z, model.focal_px, lr, model.disparity_error_px) / z
    found = []
    if geometry.overlap_fraction < OVERLAP_LIMIT:
        found.append(
            Finding(
                "overlap",
                f"at {z:g} m the left and right views overlap by only "
                f"{100 * geometry.overlap_fraction:.0f} % (disparity {geometry.disparity_px:,.0f}"
                f" px of {profile.image_size[0]} px): too close for C_lr = {lr:g} m",
            )
        )
    if stereo > STEREO_LIMIT:
        found.append(
            Finding(
                "C_lr_too_small",
                f"at {z:g} m a {model.disparity_error_px:g} px disparity error alone is "
                f"{100 * stereo:.1f} % of the depth (disparity {geometry.disparity_px:.0f} px): "
                f"C_lr = {lr:g} m is too small for this range and focal length",
            )
        )
    if geometry.anchor_error_fraction > ANCHOR_LIMIT:
        found.append(
            Finding(
                "C_lb_too_small",
                f"at {z:g} m the back view is only {100 * geometry.back_scale_change:.2f} % "
                f"smaller ({geometry.back_shift_px:.1f} px over half the image width): one pair "
                f"of back-camera matches fixes the depth to +-"
                f"{100 * geometry.anchor_error_fraction:.0f} % only; "
                f"C_lb = {lb:g} m is too small for this range",
            )
        )
    return found


def _fov_warning(profile: RigProfile, geometry: RangeGeometry, model: ErrorModel) -> Finding:
    width, height = profile.image_size
    return Finding(
        "fov_too_wide",
        f"the {fov_deg(model.focal_px, width):.1f} x {fov_deg(model.focal_px, height):.1f} deg"
        f" field of view is too wide for the near-orthographic (affine) rectification: a "
        f"{RELATIVE_ROTATION_DEG:g} deg rotation between cameras leaves up to "
        f"{geometry.affine_residual_px:.1f} px of non-affine shift at the corners, "
        f"{100 * geometry.affine_error_fraction:.1f} % of the {geometry.disparity_px:.0f} px "
        f"disparity at {geometry.range_m:g} m",
    )


# --------------------------------------------------------------------------- the whole check


@dataclass(frozen=True)
class RigCheck:
    """Everything ``rigkit rig check`` reports for one profile."""

    profile: RigProfile
    model: ErrorModel
    geometry: tuple[RangeGeometry, ...]
    budget: tuple[BudgetRow, ...]
    reach_m: tuple[tuple[float, float | None], ...]
    findings: tuple[Finding, ...]

    @property
    def straight_line_lb_m(self) -> float | None:
        """The straight left-to-back distance implied by C_lb and the back offset, metres."""
        if self.profile.back_offset_m is None:
            return None
        right, up = self.profile.back_offset_m
        return math.sqrt(self.profile.baseline_lb.value_m**2 + right**2 + up**2)


def check_rig(
    profile: RigProfile,
    ranges_m: Sequence[float],
    disparity_error_px: float = DISPARITY_ERROR_PX,
    offset_error_px: float | None = None,
    capture_findings: Sequence[Finding] = (),
    frames: int = 1,
    shimmer_px: float = SHIMMER_PX,
    shimmer_corr_px: float | None = None,
) -> RigCheck:
    """Run the geometry check and the error budget; ``capture_findings`` (from
    :func:`rigkit.capture.checks.check_capture`, when frames were given) are appended
    to the geometry warnings. The offset's error: see :meth:`ErrorModel.from_profile`."""
    for value in ranges_m:
        if not value > 0:
            raise InputError(f"ranges must be > 0 m, got {value:g}")
    model = ErrorModel.from_profile(
        profile, disparity_error_px, offset_error_px, frames, shimmer_px, shimmer_corr_px
    )
    geometry = tuple(geometry_at(profile, z, disparity_error_px) for z in ranges_m)
    findings = geometry_warnings(profile, geometry, model)
    findings += capture_findings
    return RigCheck(
        profile=profile,
        model=model,
        geometry=geometry,
        budget=tuple(budget_row(model, z) for z in BUDGET_RANGES_M),
        reach_m=tuple((p, range_reaching(model, p)) for p in TARGET_FRACTIONS),
        findings=tuple(findings),
    )


def check_to_dict(check: RigCheck) -> dict[str, Any]:
    """The check as JSON-ready data (lengths in m, angles in degrees, fractions not %)."""
    profile, model = check.profile, check.model
    width, height = profile.image_size
    return {
        "profile": {"source": str(profile.source), **rig_to_dict(profile)},
        "focal_px": model.focal_px,
        "image_size_px": [width, height],
        "fov_deg": {
            "horizontal": fov_deg(model.focal_px, width),
            "vertical": fov_deg(model.focal_px, height),
            "diagonal": fov_deg(model.focal_px, math.hypot(width, height)),
        },
        "straight_line_lb_m": check.straight_line_lb_m,
        "distortion": {
            "k1_k2_p1_p2_k3": list(profile.distortion),
            "corner_fraction": corner_distortion(profile)[0],
            "corner_px": corner_distortion(profile)[1],
            "fitted_from_views": bool(profile.pipeline_settings().distortion_terms),
            "corner_error_px": model.lens_corner_px,
            "disparity_error_px": model.lens_error_px,
        },
        "assumptions": {
            "disparity_error_px": model.disparity_error_px,
            "offset_error_px": model.offset_error_px,
            "offset_frames_per_position": model.frames,
            "offset_shimmer_px": model.shimmer_px,
            "offset_shimmer_corr_px": model.shimmer_corr_px,
            "lens_error_px": model.lens_error_px,
            "focal_tolerance": model.focal_tolerance,
            "relative_rotation_deg": RELATIVE_ROTATION_DEG,
        },
        "geometry": [
            {**asdict(g), "affine_error_fraction": g.affine_error_fraction} for g in check.geometry
        ],
        "error_budget": [
            {**asdict(row), "total_m": row.total_m, "total_fraction": row.total_fraction}
            for row in check.budget
        ],
        "range_reaching_m": {f"{p:g}": z for p, z in check.reach_m},
        "warnings": [asdict(finding) for finding in check.findings],
    }
