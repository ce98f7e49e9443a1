"""Focal length and field-of-view conversions between millimetres, 35 mm-equivalent
focal lengths and pixels (square pixels, pinhole model)."""

from __future__ import annotations

import math

FULL_FRAME_DIAGONAL_MM = math.hypot(36.0, 24.0)
"""Diagonal of the 36 x 24 mm frame that 35 mm-equivalent focal lengths refer to (43.27 mm)."""


def focal_px_from_mm(f_mm: float, sensor_width_mm: float, width_px: int) -> float:
    """Focal length in pixels from the real focal length in mm and the sensor width in mm.

    ``sensor_width_mm`` is the width of the area the ``width_px``-wide image covers;
    pixels are assumed square.
    """
    _require_positive(f_mm=f_mm, sensor_width_mm=sensor_width_mm, width_px=width_px)
    return f_mm * width_px / sensor_width_mm


def focal_px_from_35mm_equivalent(
    f_eq_mm: float,
    sensor_mm: tuple[float, float] | None,
    resolution: tuple[int, int],
) -> float:
    """Focal length in pixels from a 35 mm-equivalent focal length.

    The equivalence is defined on the diagonal: crop factor = 43.27 mm / sensor
    diagonal, real focal length = ``f_eq_mm`` / crop factor, then pixels via the
    sensor width. (Dividing by the 36 mm width instead is ~4 % off on a 4:3 sensor.)

    The result depends only on the sensor's aspect ratio, not its size:
    f_px = f_eq_mm * (diagonal / width) * width_px / 43.27. With ``sensor_mm`` None
    the image's own aspect ratio is used (square pixels, whole sensor imaged).
    """
    width_px, height_px = resolution
    width_mm, height_mm = sensor_mm if sensor_mm is not None else (float(width_px), height_px)
    _require_positive(f_eq_mm=f_eq_mm, sensor_width_mm=width_mm, sensor_height_mm=height_mm)
    crop_factor = FULL_FRAME_DIAGONAL_MM / math.hypot(width_mm, height_mm)
    return focal_px_from_mm(f_eq_mm / crop_factor, width_mm, width_px)


def fov_deg(focal_px: float, size_px: float) -> float:
    """Full field of view in degrees across ``size_px`` pixels (centred principal point)."""
    _require_positive(focal_px=focal_px, size_px=size_px)
    return math.degrees(2.0 * math.atan(size_px / (2.0 * focal_px)))


def _require_positive(**values: float) -> None:
    for name, value in values.items():
        if not value > 0:
            raise ValueError(f"{name} must be > 0, got {value!r}")
