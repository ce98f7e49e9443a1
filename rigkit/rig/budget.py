"""The error budget: how far a depth at a given range may be off, each source alone and
together (the rig check built on it is :mod:`rigkit.rig.check`).

Notation (paper, Sec. 2-3): z depth in metres, f focal length in pixels, C_lr the
left-right baseline and C_lb the left-back distance along the viewing axis, in metres.

Error budget, each source alone, to first order (|dz| in metres):

* disparity d = f * C_lr / z (pixels)
* a disparity error dd (pixels):             dz = z**2 * dd / (f * C_lr)
* a relative error e in f, C_lr or C_lb:     dz = z * e
* an error dq in the global disparity offset: dz = z**2 * dq / (f * C_lr), with dq
  measured on rendered scenes as a function of heat shimmer and burst length
  (:func:`rigkit.rig.bursts.expected_offset_error_px`)
* a lens distortion error that moves the image corner by dc (pixels): where a
  rotation g between cameras moves the image by s = f tan(g), a radial error growing
  as r**3 changes by up to 3 dc s / r_c between the two positions of a point: a
  disparity error dd = 3 dc s / r_c (r_c: the corner's distance from the centre, px)

The offset q is what the back camera fixes (paper Sec. 3, ambiguity removal); C_lb
enters through the anchor depth z = C_lb / (m_l / m_b - 1), so its relative error
carries over to z. The sources are independent, so the total is their root-sum-square.
This is the plain-stereo view: where the back camera's anchor lies at the same depth,
errors in f and C_lr cancel there (docs/rig-profiles.md, "Reading the error budget").

A profile whose scale the lasers calibrated (``rigkit rig calibrate``) was measured
through that anchor: its C_lb tolerance is the fit's at the depth the calibration pinned
the scale at (``anchor_m``), and an error e in f * C_lr only stretches depth about it,
dz = z * e * |1 - z / anchor| (the calibration's model, :mod:`rigkit.rig.calibration`),
so the budget takes the calibrated tolerances that way.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from rigkit.geometry import distort
from rigkit.rig.bursts import (
    OFFSET_FLOOR_PX,
    default_shimmer,
    expected_offset_error_px,
    reference_scale,
)
from rigkit.rig.defaults import DISPARITY_ERROR_PX
from rigkit.rig.formulas import depth_error_from_disparity, depth_error_from_relative, disparity_px
from rigkit.rig.profile import Baseline, RigProfile

BUDGET_RANGES_M = (100.0, 150.0, 200.0, 250.0, 300.0, 350.0, 400.0, 450.0, 500.0)
TARGET_FRACTIONS = (0.01, 0.03)
"""Relative depth errors whose onset range the check reports (1 % and 3 %)."""
RELATIVE_ROTATION_DEG = 1.0
"""Rotation between cameras assumed for the affine residual (paper: up to 1 deg about x, y)."""
LENS_FIT_CORNER_PX = 0.5
"""Error at the image corner of the distortion the pipeline fits from the views, px at
REFERENCE_SIZE (field scenes with 0.3 px shimmer, docs/results-log.md; scaled by the image
size for other sizes)."""


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
        return LENS_FIT_CORNER_PX * reference_scale(profile.image_size)
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
    """What ``offset_error_px`` was derived from (None: it was given)."""
    anchor_m: float | None = None
    """The depth a laser calibration pinned the scale at, m: f's and C_lr's errors
    stretch depth about it (None: a taped profile, the plain-stereo view)."""

    @classmethod
    def from_profile(
        cls,
        profile: RigProfile,
        disparity_error_px: float = DISPARITY_ERROR_PX,
        offset_error_px: float | None = None,
        frames: int = 1,
        shimmer_px: float | None = None,
        shimmer_corr_px: float | None = None,
    ) -> ErrorModel:
        """The model for a profile (its focal length, tolerances, baselines and lens).
        The offset's error is ``offset_error_px`` where given, else what ``frames`` per
        position under ``shimmer_px`` of shimmer correlated over ``shimmer_corr_px``
        leave (:func:`rigkit.rig.bursts.expected_offset_error_px`); either shimmer figure
        left out is moderate air's at the profile's focal length
        (:func:`rigkit.rig.bursts.default_shimmer`)."""
        derived = offset_error_px is None
        moderate = default_shimmer(profile.focal_px)
        shimmer_px = moderate[0] if shimmer_px is None else shimmer_px
        shimmer_corr_px = moderate[1] if shimmer_corr_px is None else shimmer_corr_px
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
            anchor_m=profile.calibration.reference_depth_m if profile.calibration else None,
        )

    @property
    def quadratic_term(self) -> float:
        """a in total(z) = z * sqrt((a z)**2 + b**2): disparity, offset and lens errors, 1/m."""
        pixels = math.hypot(self.disparity_error_px, self.offset_error_px, self.lens_error_px)
        return pixels / (self.focal_px * self.baseline_lr.value_m)

    @property
    def constant_term(self) -> float:
        """b in total(z) = z * sqrt((a z)**2 + b**2): f, C_lr and C_lb tolerances (at the
        anchor of a calibrated profile, C_lb's alone)."""
        if self.anchor_m is not None:
            return self.baseline_lb.relative_tolerance
        return math.hypot(self.shape_tolerance, self.baseline_lb.relative_tolerance)

    @property
    def shape_tolerance(self) -> float:
        """The relative tolerance of f * C_lr: f's and C_lr's together."""
        return math.hypot(self.focal_tolerance, self.baseline_lr.relative_tolerance)

    def stretch(self, range_m: float) -> float:
        """What an error in f or C_lr does at ``range_m`` as a share of its plain-stereo
        z * e: 1, or |1 - z / anchor| for a calibrated profile."""
        return 1.0 if self.anchor_m is None else abs(1.0 - range_m / self.anchor_m)


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
        from_baseline_lr_m=depth_error_from_relative(
            range_m, model.baseline_lr.relative_tolerance * model.stretch(range_m)),
        from_baseline_lb_m=depth_error_from_relative(range_m, model.baseline_lb.relative_tolerance),
        from_focal_m=depth_error_from_relative(
            range_m, model.focal_tolerance * model.stretch(range_m)),
        from_offset_m=depth_error_from_disparity(
            range_m, model.focal_px, lr, model.offset_error_px
        ),
        from_lens_m=depth_error_from_disparity(range_m, model.focal_px, lr, model.lens_error_px),
    )


def range_reaching(model: ErrorModel, fraction: float) -> float | None:
    """The range in metres at which the total relative error reaches ``fraction``.

    total / z = sqrt((a z)**2 + b**2), so z = sqrt(fraction**2 - b**2) / a. Returns 0.0
    when the range-independent part b alone reaches it, None when it is never reached.
    For a calibrated profile, total / z = sqrt((a z)**2 + b**2 + (e (1 - z / anchor))**2)
    with e the f * C_lr tolerance: the range beyond the anchor where it reaches
    ``fraction`` (0.0 where it does at every range).
    """
    a, b = model.quadratic_term, model.constant_term
    if model.anchor_m is not None:
        return _anchored_reach(a, b, model.shape_tolerance, model.anchor_m, fraction)
    if b >= fraction:
        return 0.0
    if a == 0.0:
        return None
    return math.sqrt(fraction**2 - b**2) / a


def _anchored_reach(a: float, b: float, e: float, anchor: float, fraction: float) -> float:
    """The larger root of (a z)**2 + b**2 + e**2 (1 - z/anchor)**2 = fraction**2, 0.0 where
    there is none beyond 0 (the fraction reached at every range)."""
    quad = a * a + (e / anchor) ** 2
    lin = -2 * e * e / anchor
    const = b * b + e * e - fraction**2
    disc = lin * lin - 4 * quad * const
    if disc < 0:
        return 0.0
    far = (-lin + math.sqrt(disc)) / (2 * quad)
    return far if far > 0 else 0.0
