"""Rig profiles (the three cameras, two baselines and the rangefinder, from YAML) and the
rig check's error budget and geometry warnings."""

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
