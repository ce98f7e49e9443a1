"""``rigkit rig check``: the error budget at the planned ranges and warnings where the
rig's geometry cannot deliver depth there (the capture (EXIF) check is
:mod:`rigkit.capture.checks`)."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import asdict, dataclass
from typing import Any

from rigkit.errors import InputError
from rigkit.rig.budget import (
    BUDGET_RANGES_M,
    RELATIVE_ROTATION_DEG,
    TARGET_FRACTIONS,
    BudgetRow,
    ErrorModel,
    budget_row,
    corner_distortion,
    range_reaching,
)
from rigkit.rig.defaults import DISPARITY_ERROR_PX
from rigkit.rig.findings import Finding
from rigkit.rig.formulas import (
    affine_residual_px,
    anchor_error_fraction,
    back_shift_px,
    depth_error_from_disparity,
    disparity_px,
    triangulation_angle_deg,
)
from rigkit.rig.optics import fov_deg
from rigkit.rig.profile import RigProfile, rig_to_dict

STEREO_LIMIT = 0.01
"""Warn when the disparity error alone exceeds this fraction of the depth."""
ANCHOR_LIMIT = 0.10
"""Warn when one pair of back-camera matches fixes the depth only to worse than this."""
AFFINE_LIMIT = 0.01
"""Warn when the non-affine residual exceeds this fraction of the disparity."""
OVERLAP_LIMIT = 0.5
"""Warn when the left and right views overlap by less than this fraction of the width."""


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
    shimmer_px: float | None = None,
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
    findings = geometry_warnings(profile, geometry, model) + _goal_warning(model)
    findings += capture_findings
    return RigCheck(
        profile=profile,
        model=model,
        geometry=geometry,
        budget=tuple(budget_row(model, z) for z in BUDGET_RANGES_M),
        reach_m=tuple((p, range_reaching(model, p)) for p in TARGET_FRACTIONS),
        findings=tuple(findings),
    )


def _goal_warning(model: ErrorModel) -> list[Finding]:
    """A warning where the profile's tolerances alone put 1 % depth error out of reach
    at every range (the table says so too; a warning says what to do)."""
    goal = TARGET_FRACTIONS[0]
    if range_reaching(model, goal) != 0.0:
        return []
    fixed = 100 * model.constant_term
    why = (f"the calibrated C_lb tolerance ({fixed:.2f} %) with the range's own errors "
           "leaves no range within it" if model.anchor_m else
           f"the f, C_lr and C_lb tolerances alone give {fixed:.2f} %")
    return [Finding(
        "budget", f"{100 * goal:g} % depth error is out of reach at every range: {why}",
        redo="measure the baselines to better than their tolerances, or calibrate the "
        "rig's scale from a session's laser targets (rigkit rig calibrate)")]


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
