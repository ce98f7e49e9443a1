"""What the depth pipeline is told of the rig: the facts of its cameras and baselines
(:class:`RigGeometry`), as against how to process (:mod:`rigkit.pipeline.settings`)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from rigkit.errors import InputError
from rigkit.geometry import NO_DISTORTION, Distortion, distortion_coefficients


@dataclass(frozen=True)
class RigGeometry:
    """The only calibration the method needs: focal length (px) and two baselines (m),
    plus the lens distortion where it is known (OpenCV ``k1, k2, p1, p2, k3`` on
    normalised coordinates about the image centre; zeros = none)."""

    focal_px: float
    baseline_lr_m: float
    baseline_lb_m: float
    distortion: Distortion = NO_DISTORTION

    def __post_init__(self) -> None:
        for name in ("focal_px", "baseline_lr_m", "baseline_lb_m"):
            value = getattr(self, name)
            if not np.isfinite(value) or value <= 0:
                raise InputError(f"{name} must be a positive number, got {value!r}")
        try:
            object.__setattr__(self, "distortion", distortion_coefficients(self.distortion))
        except ValueError as exc:
            raise InputError(f"distortion: {exc}") from None
