"""What the depth pipeline is told of the rig: the facts of its cameras and baselines
(:class:`RigGeometry`), as against how to process (:mod:`rigkit.pipeline.settings`)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from rigkit.errors import InputError
from rigkit.geometry import NO_DISTORTION, Distortion, distortion_coefficients

Point = tuple[float, float]
VIEWS = ("left", "right", "back")
CENTRED: tuple[Point, Point, Point] = ((0.0, 0.0),) * 3


@dataclass(frozen=True)
class RigGeometry:
    """The only calibration the method needs: focal length (px) and two baselines (m),
    plus what else is known of the cameras: the lens distortion (OpenCV ``k1, k2, p1,
    p2, k3`` on normalised coordinates about the principal point; zeros = none), each
    view's principal point and whether one camera took the three views.

    ``principal_points_px``: ((x right, y down) left, right, back) px from the image
    centre ((W - 1) / 2, (H - 1) / 2), where the rig profile gives them
    (:func:`rigkit.rig.camera.intrinsics`), else zeros: where the lens stage's prior
    holds each view's principal point (:mod:`rigkit.pipeline.distortion`).
    ``one_camera``: one camera moved between the three positions, so the views share
    one principal point, fitted once (False: three cameras, each with its own)."""

    focal_px: float
    baseline_lr_m: float
    baseline_lb_m: float
    distortion: Distortion = NO_DISTORTION
    principal_points_px: tuple[Point, Point, Point] = CENTRED
    one_camera: bool = False

    def __post_init__(self) -> None:
        for name in ("focal_px", "baseline_lr_m", "baseline_lb_m"):
            value = getattr(self, name)
            if not np.isfinite(value) or value <= 0:
                raise InputError(f"{name} must be a positive number, got {value!r}")
        try:
            object.__setattr__(self, "distortion", distortion_coefficients(self.distortion))
        except ValueError as exc:
            raise InputError(f"distortion: {exc}") from None
        points = tuple((float(x), float(y)) for x, y in self.principal_points_px)
        if len(points) != 3 or not np.all(np.isfinite(points)):
            raise InputError(f"principal_points_px: three finite (x, y) offsets, got "
                             f"{self.principal_points_px!r}")
        if self.one_camera and len(set(points)) > 1:
            raise InputError(f"one camera took the three views, but their principal points "
                             f"differ: {points}")
        object.__setattr__(self, "principal_points_px", points)
