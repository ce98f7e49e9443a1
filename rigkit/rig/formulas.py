"""The rig's geometry in formulas (paper, Sec. 2-3).

Notation: z depth in metres, f focal length in pixels, C_lr the left-right baseline and
C_lb the left-back distance along the viewing axis, in metres; the disparity d = f C_lr
/ z in pixels.
"""

from __future__ import annotations

import math


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
