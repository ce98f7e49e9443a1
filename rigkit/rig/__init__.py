"""Rig profiles (the three cameras, two baselines and the rangefinder, from YAML) and the
rig check's error budget and geometry warnings.

Its public names are imported on first use (:mod:`rigkit.core.lazy`): a module that
reads a profile does not load the error budget, and the pipeline behind it, with it.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from rigkit.core.lazy import exports

if TYPE_CHECKING:
    from rigkit.rig.budget import ErrorModel, budget_row
    from rigkit.rig.check import RigCheck, check_rig, check_to_dict
    from rigkit.rig.findings import Finding
    from rigkit.rig.optics import focal_px_from_35mm_equivalent, focal_px_from_mm, fov_deg
    from rigkit.rig.profile import (
        CAMERA_ROLES,
        Baseline,
        CameraSpec,
        RangefinderSpec,
        RigProfile,
        dump_rig,
        load_rig,
        rig_from_data,
        rig_to_dict,
    )

__all__ = [
    "CAMERA_ROLES",
    "Baseline",
    "CameraSpec",
    "ErrorModel",
    "Finding",
    "RangefinderSpec",
    "RigCheck",
    "RigProfile",
    "budget_row",
    "check_rig",
    "check_to_dict",
    "dump_rig",
    "focal_px_from_35mm_equivalent",
    "focal_px_from_mm",
    "fov_deg",
    "load_rig",
    "rig_from_data",
    "rig_to_dict",
]

__getattr__ = exports(__name__, {
    "Baseline": "profile",
    "CAMERA_ROLES": "profile",
    "CameraSpec": "profile",
    "ErrorModel": "budget",
    "Finding": "findings",
    "RangefinderSpec": "profile",
    "RigCheck": "check",
    "RigProfile": "profile",
    "budget_row": "budget",
    "check_rig": "check",
    "check_to_dict": "check",
    "dump_rig": "profile",
    "focal_px_from_35mm_equivalent": "optics",
    "focal_px_from_mm": "optics",
    "fov_deg": "optics",
    "load_rig": "profile",
    "rig_from_data": "profile",
    "rig_to_dict": "profile",
})
