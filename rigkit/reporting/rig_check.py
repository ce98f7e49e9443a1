"""``rigkit rig check`` as text for people: summary, geometry, error budget, warnings."""

from __future__ import annotations

import math
import textwrap
from collections.abc import Sequence

from rigkit.core.tables import render_table
from rigkit.reporting.scale import scale_source
from rigkit.rig.budget import RELATIVE_ROTATION_DEG, ErrorModel, corner_distortion
from rigkit.rig.check import RigCheck
from rigkit.rig.formulas import affine_residual_px
from rigkit.rig.optics import fov_deg
from rigkit.rig.profile import CAMERA_ROLES, RigProfile


def format_check(check: RigCheck) -> str:
    """The check as text for people: summary, geometry, error budget, warnings."""
    sections = [
        _summary(check),
        _geometry_table(check),
        _budget_table(check),
        _warnings(check),
    ]
    return "\n\n".join(sections)


def _summary(check: RigCheck) -> str:
    profile, focal = check.profile, check.model.focal_px
    width, height = profile.image_size
    lr, lb = profile.baseline_lr, profile.baseline_lb
    lines = [
        f"rig {profile.name}  ({profile.source})",
        _field("cameras", f"{_camera_models(profile)}, {width} x {height} px"),
        _field(
            "focal length",
            f"{focal:,.0f} px +-{100 * check.model.focal_tolerance:g} %{_focal_origin(profile)}",
        ),
        _field(
            "field of view",
            f"{fov_deg(focal, width):.2f} x {fov_deg(focal, height):.2f} deg "
            f"(horizontal x vertical; diagonal {fov_deg(focal, math.hypot(width, height)):.2f})",
        ),
        _field(
            "baselines",
            f"C_lr {lr.value_m:g} +- {lr.tolerance_m:g} m, "
            f"C_lb {lb.value_m:g} +- {lb.tolerance_m:g} m (along the viewing axis)",
        ),
        _field("scale", scale_source(profile)),
        _field("lens", _lens(profile)),
        _field("back camera", _back_offset(check)),
        _field("rangefinder", _rangefinder(profile)),
        _field(
            "affine check",
            f"a {RELATIVE_ROTATION_DEG:g} deg rotation between cameras leaves "
            f"{affine_residual_px(focal, (width, height), RELATIVE_ROTATION_DEG):.2f} px of "
            "non-affine shift at the corners",
        ),
    ]
    return "\n".join(lines)


def _lens(profile: RigProfile) -> str:
    fitted = profile.pipeline_settings().distortion_terms > 0
    if not any(profile.distortion):
        if fitted:
            return "none given; fitted from the three views"
        return ("none, and not fitted (pipeline.distortion_terms: 0): an uncorrected lens "
                "bend costs percents in depth")
    fraction, px = corner_distortion(profile)
    terms = ", ".join(f"{v:.4g}" for v in profile.distortion)
    spec = profile.cameras["left"].lens_profile
    source = f"lensfun {spec.lens} at {spec.focal_mm:.1f} mm, " if spec else ""
    return (f"{source}k1,k2,p1,p2,k3 = {terms}: {100 * fraction:.2f} % ({px:.1f} px) at the "
            f"corner; {'refined from' if fitted else 'not refined from'} the three views")


def _field(label: str, text: str) -> str:
    return f"  {label:<14} {text}"


def _camera_models(profile: RigProfile) -> str:
    specs = [profile.cameras[role] for role in CAMERA_ROLES]
    if profile.one_camera:
        return f"{specs[0].model} (one camera moved between the positions: one principal point)"
    if all(spec == specs[0] for spec in specs):
        return f"{specs[0].model} (one spec for left, right and back)"
    return "; ".join(f"{role}: {profile.cameras[role].model}" for role in CAMERA_ROLES)


def _focal_origin(profile: RigProfile) -> str:
    given = profile.cameras["left"].focal_given
    sensor = profile.cameras["left"].sensor_mm
    if given is None or given[0] == "px" or sensor is None:
        return ""
    form, value = given
    kind = "35 mm-equivalent" if form == "equivalent_35mm_mm" else "real"
    return f"  (from {value:g} mm {kind}, sensor {sensor[0]:g} x {sensor[1]:g} mm)"


def _back_offset(check: RigCheck) -> str:
    offset, straight = check.profile.back_offset_m, check.straight_line_lb_m
    if offset is None or straight is None:
        return "offset from the left camera's axis not given"
    if offset == (0.0, 0.0):
        return "straight behind the left camera"
    right, up = offset
    along = check.profile.baseline_lb.value_m
    return (
        f"{_signed(up, 'up', 'down')} and {_signed(right, 'right', 'left')} of the left "
        f"camera's axis\n{'':17}(straight-line distance {straight:.3f} m; "
        f"C_lb = {along:g} m is along the axis)"
    )


def _signed(value: float, positive: str, negative: str) -> str:
    return f"{abs(value):g} m {positive if value >= 0 else negative}"


def _rangefinder(profile: RigProfile) -> str:
    spec = profile.rangefinder
    if spec is None:
        return "none"
    parts = [spec.protocol]
    if spec.port is not None:
        parts.append(f"{spec.port} at {spec.baud} baud")
    if spec.offset_m is not None:
        right, up, forward = spec.offset_m
        parts.append(
            f"{_signed(right, 'right', 'left')}, {_signed(up, 'up', 'down')}, "
            f"{_signed(forward, 'forward', 'back')} of the left camera"
        )
    return ", ".join(parts)


def _geometry_table(check: RigCheck) -> str:
    header = [
        ("range", "m"),
        ("C_lr/z", ""),
        ("angle", "deg"),
        ("disparity", "px"),
        ("overlap", "%"),
        ("back scale", "%"),
        ("back shift", "px"),
        ("anchor", "+-%"),
        ("affine", "% of d"),
    ]
    rows = [
        [
            f"{g.range_m:g}",
            f"1/{1 / g.baseline_ratio_lr:.0f}",
            f"{g.triangulation_angle_deg:.3f}",
            f"{g.disparity_px:.1f}",
            f"{100 * g.overlap_fraction:.0f}",
            f"{100 * g.back_scale_change:.3f}",
            f"{g.back_shift_px:.1f}",
            f"{100 * g.anchor_error_fraction:.1f}",
            f"{100 * g.affine_error_fraction:.2f}",
        ]
        for g in check.geometry
    ]
    legend = (
        "  angle: triangulation angle; overlap: of the left and right views; back scale and\n"
        "  shift: how much smaller the back view is (shift over half the image width);\n"
        f"  anchor: depth error from one back-camera pair matched to "
        f"{check.model.disparity_error_px:g} px;\n"
        "  affine: the corner residual above as a fraction of the disparity d"
    )
    return "geometry at the chosen ranges\n" + _table(header, rows) + "\n" + legend


def _budget_table(check: RigCheck) -> str:
    model = check.model
    lr, lb = model.baseline_lr, model.baseline_lb
    header = [
        ("range", "m"),
        ("disparity", "px"),
        ("disparity", f"{model.disparity_error_px:g} px"),
        ("C_lr", f"{lr.tolerance_m:g} m"),
        ("C_lb", f"{lb.tolerance_m:g} m"),
        ("focal", f"{100 * model.focal_tolerance:g} %"),
        ("offset", f"{model.offset_error_px:.2g} px"),
        ("lens", f"{model.lens_error_px:.2g} px"),
        ("total", "m"),
        ("total", "%"),
    ]
    rows = [
        [
            f"{row.range_m:g}",
            f"{row.disparity_px:.1f}",
            f"{row.from_disparity_m:.2f}",
            f"{row.from_baseline_lr_m:.2f}",
            f"{row.from_baseline_lb_m:.2f}",
            f"{row.from_focal_m:.2f}",
            f"{row.from_offset_m:.2f}",
            f"{row.from_lens_m:.2f}",
            f"{row.total_m:.2f}",
            f"{100 * row.total_fraction:.2f}",
        ]
        for row in check.budget
    ]
    reach = [f"  {100 * p:g} % depth error: {_reach_text(check, z)}" for p, z in check.reach_m]
    note = (
        "  Each column is one source alone (dz = z^2 dd / (f C_lr) for disparity, offset and\n"
        "  lens, dz = z e for a relative error e); total is their root-sum-square. f and C_lr\n"
        "  errors cancel at the back-camera anchor's depth: see docs/rig-profiles.md.\n"
        f"  lens: the disparity error of a lens model {model.lens_corner_px:.2g} px off at the "
        f"corner, views turned by {RELATIVE_ROTATION_DEG:g} deg.\n"
        f"  offset: {_offset_basis(model)}"
    )
    if model.anchor_m is not None:
        note += (f"\n  laser-calibrated: f and C_lr errors only stretch depth about the "
                 f"{model.anchor_m:.0f} m the calibration\n  pinned the scale at "
                 "(dz = z e |1 - z / anchor|); C_lb's tolerance is the fit's.")
    title = "depth error budget, metres (source and its size in the header)"
    return "\n".join([title, _table(header, rows), *reach, note])


def _offset_basis(model: ErrorModel) -> str:
    if model.frames is None or model.shimmer_px is None:
        return "as given (--offset-error-px)."
    frames = f"{model.frames} frame{'s' if model.frames > 1 else ''}"
    corr = "" if model.shimmer_corr_px is None else f" over {model.shimmer_corr_px:.3g} px"
    return (
        f"{frames} per position under {model.shimmer_px:.2g} px RMS of heat shimmer{corr}\n"
        "  (--frames, --shimmer-px, --shimmer-corr-px); N frames divide its share by "
        "about sqrt(N)."
    )


def _reach_text(check: RigCheck, range_m: float | None) -> str:
    if range_m is None:
        return "never (no range-dependent error assumed)"
    if range_m == 0.0:
        fixed = 100 * check.model.constant_term
        if check.model.anchor_m is not None:
            return f"exceeded at every range (the calibrated C_lb alone gives {fixed:.2f} %)"
        return f"exceeded at every range (f, C_lr and C_lb tolerances alone give {fixed:.2f} %)"
    last = check.budget[-1].range_m
    beyond = f" (beyond {last:g} m)" if range_m > last else ""
    return f"reached at {range_m:,.0f} m{beyond}"


def _warnings(check: RigCheck) -> str:
    if not check.findings:
        return "warnings: none"
    items = (
        textwrap.fill(finding.message, width=96, initial_indent="  - ", subsequent_indent="    ")
        for finding in check.findings
    )
    return f"warnings ({len(check.findings)}):\n" + "\n".join(items)


def _table(header: Sequence[tuple[str, str]], rows: Sequence[Sequence[str]]) -> str:
    """Right-aligned columns under a two-line header (name, unit), indented by two."""
    names = [f"{name}\n{unit}" for name, unit in header]
    return render_table(names, rows, indent=2, rule=False)
