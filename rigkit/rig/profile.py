"""Rig profiles: the three cameras, the two baselines and the rangefinder, read from YAML.

A rig is described once, in a profile such as ``rigs/p1000-tripod.yaml``, and
loaded by :func:`load_rig` into a frozen :class:`RigProfile`. The format is
documented in ``docs/rig-profiles.md``; in short::

    version: 1
    name: p1000-tripod
    camera:                      # shared by left, right and back (or `cameras:` with each)
      model: Nikon Coolpix P1000
      sensor_mm: [6.17, 4.6275]  # [width, height] of the area the image covers
      resolution: [4608, 3456]   # [width, height] in pixels
      focal_length: {equivalent_35mm_mm: 400, tolerance_fraction: 0.01}
    baselines:
      C_lr: {value_m: 2.0, tolerance_m: 0.02}
      C_lb: {value_m: 2.0, tolerance_m: 0.02}

Units are part of every key name. Errors name the file, the dotted key
(``cameras.left.focal_length.mm``) and the offending value, on one line.

Coordinates follow the paper's camera frame of the left camera, but with ``up``
positive: x to the right (looking along the viewing direction), y up, z forward
along the viewing direction.
"""

from __future__ import annotations

import re
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from types import MappingProxyType
from typing import Any

from rigkit.core.yamlfile import KeyPath, dump_yaml, read_strict_yaml
from rigkit.errors import InputError
from rigkit.geometry import Distortion
from rigkit.pipeline import RigGeometry
from rigkit.pipeline.settings import PipelineSettings, setting_names, setting_type
from rigkit.rig.camera import CameraSpec, Intrinsics, camera_to_dict, intrinsics, read_camera
from rigkit.rig.defaults import MAX_RANGE_M
from rigkit.rig.provenance import Calibration, calibration_to_dict, read_calibration

PROFILE_VERSION = 1
CAMERA_ROLES = ("left", "right", "back")
FOCAL_AGREEMENT = 0.001
"""The three cameras' focal lengths may differ by at most this fraction (0.1 %)."""
_MAX_BASELINE_M = 100.0
_MIN_BASELINE_M = 0.01
_MAX_OFFSET_M = 10.0
_MAX_BAUD = 4_000_000
_PROTOCOL_PATTERN = re.compile(r"[a-z0-9][a-z0-9_-]*")
AZIMUTH_REFERENCES = ("true", "magnetic")
"""What a rangefinder's azimuths may be measured from (profile key ``rangefinder.azimuth``)."""


# --------------------------------------------------------------------------- the profile


@dataclass(frozen=True)
class Baseline:
    """A baseline in metres and its measurement tolerance (one-sided bound, metres)."""

    value_m: float
    tolerance_m: float

    @property
    def relative_tolerance(self) -> float:
        """``tolerance_m / value_m``."""
        return self.tolerance_m / self.value_m


@dataclass(frozen=True)
class RangefinderSpec:
    """The laser rangefinder used for spot checks.

    ``protocol`` names how readings arrive (``manual``: typed in by hand);
    ``port``/``baud`` for a serial device; ``offset_m`` is (right, up, forward) of
    its aperture from the left camera's optical centre, in metres, None if unknown.
    ``max_range_m``: the longest range the device measures (None: its protocol's,
    :func:`rigkit.rangefinder.ranging.max_range_m`); longer readings are refused.
    ``azimuth`` says what the readings' azimuths are measured from: ``true`` north
    (the default) or ``magnetic`` north, which lies ``declination_deg`` degrees east
    of true north (negative: west), so true = magnetic + declination.
    """

    protocol: str
    port: str | None
    baud: int | None
    offset_m: tuple[float, float, float] | None
    max_range_m: float | None = None
    azimuth: str = "true"
    declination_deg: float = 0.0

    def true_azimuth_deg(self, azimuth_deg: float) -> float:
        """A reading's azimuth as degrees clockwise from true north, in [0, 360)."""
        return (azimuth_deg + self.declination_deg) % 360.0


@dataclass(frozen=True)
class RigProfile:
    """A three-camera rig as loaded from a profile.

    ``baseline_lr`` is C_lr, the distance between the left and right optical
    centres (along x). ``baseline_lb`` is C_lb, how far the back camera sits behind
    the left one *along the viewing axis* (z). ``back_offset_m`` is (x, y) of the
    back camera's optical centre relative to the point C_lb behind the left one:
    x positive to the right, y positive up; None if not known.
    ``nominal_range_m`` is the range the rig is designed for, if stated.
    ``pipeline`` holds the depth pipeline settings the profile overrides (names of
    :class:`rigkit.pipeline.settings.PipelineSettings`).
    """

    name: str
    cameras: Mapping[str, CameraSpec] = field(hash=False)
    baseline_lr: Baseline
    baseline_lb: Baseline
    back_offset_m: tuple[float, float] | None
    rangefinder: RangefinderSpec | None
    notes: str
    nominal_range_m: float | None
    source: Path = field(compare=False)
    pipeline: Mapping[str, float] = field(default_factory=dict, hash=False)
    one_camera: bool = False
    """One camera moved between the three positions (``one_camera: true``): the views
    share its principal point. False: three cameras, each with its own."""
    calibration: Calibration | None = field(default=None, compare=False, hash=False)
    """Where the scale comes from when the lasers calibrated it (None: taped)."""

    @property
    def distortion(self) -> Distortion:
        """The lens distortion shared by the three cameras; InputError if they differ
        (the pipeline models one lens)."""
        values = {cam.distortion for cam in self.cameras.values()}
        if len(values) > 1:
            raise InputError(
                f"{self.source}: cameras: distortion differs between cameras; rigkit "
                "models one lens for the three views"
            )
        return values.pop()

    def intrinsics(self, image_size: tuple[int, int] | None = None) -> Intrinsics:
        """The left camera's pinhole model for frames of ``image_size`` (W, H) px (None:
        the profile's), :func:`rigkit.rig.camera.intrinsics`: what the pipeline, the laser
        comparisons and export use."""
        size = self.image_size if image_size is None else image_size
        return intrinsics(self.cameras["left"], self.focal_px, size)

    def geometry(self) -> RigGeometry:
        """What the depth pipeline needs of the rig: f, C_lr, C_lb, the lens, each
        camera's principal point (:func:`rigkit.rig.camera.intrinsics`, at the profile's
        image size) and whether one camera took the three views."""
        size, f = self.image_size, self.focal_px
        left, right, back = (intrinsics(self.cameras[role], f, size).centre_offset_px
                             for role in CAMERA_ROLES)
        return RigGeometry(
            f, self.baseline_lr.value_m, self.baseline_lb.value_m, self.distortion,
            principal_points_px=(left, right, back), one_camera=self.one_camera,
        )

    def pipeline_settings(self) -> PipelineSettings:
        """The pipeline's defaults with this profile's overrides."""
        return PipelineSettings(**self.pipeline)  # type: ignore[arg-type]

    @property
    def focal_px(self) -> float:
        """The common focal length in pixels (mean of the three cameras).

        Raises InputError if they differ by more than 0.1 %: the pipeline assumes one f.
        """
        values = {role: cam.focal_px for role, cam in self.cameras.items()}
        low, high = min(values.values()), max(values.values())
        if (high - low) / low > FOCAL_AGREEMENT:
            listed = ", ".join(f"{role} {value:.1f} px" for role, value in values.items())
            raise InputError(
                f"{self.source}: cameras: focal lengths differ by "
                f"{100 * (high - low) / low:.2f} % ({listed}); rigkit needs one common "
                f"focal length (within {100 * FOCAL_AGREEMENT:g} %)"
            )
        return sum(values.values()) / len(values)

    @property
    def image_size(self) -> tuple[int, int]:
        """The common image size (width, height) in pixels; InputError if the cameras differ."""
        sizes = {cam.resolution for cam in self.cameras.values()}
        if len(sizes) > 1:
            listed = ", ".join(
                f"{role} {cam.resolution[0]}x{cam.resolution[1]}"
                for role, cam in self.cameras.items()
            )
            raise InputError(
                f"{self.source}: cameras: resolutions differ ({listed}); "
                "rigkit needs one common image size"
            )
        return sizes.pop()

    @property
    def focal_tolerance(self) -> float:
        """The largest of the three cameras' focal-length tolerances (fraction)."""
        return max(cam.focal_tolerance for cam in self.cameras.values())


# --------------------------------------------------------------------------- loading


def load_rig(path: str | Path) -> RigProfile:
    """Read and validate a rig profile.

    Raises InputError naming the file, the dotted key and the bad value for any
    unknown key, missing key, wrong type, implausible unit or impossible value.
    """
    path = Path(path)
    return rig_from_data(read_rig_data(path), path)


def rig_from_data(data: Any, source: Path, key_prefix: str = "") -> RigProfile:
    """Validate a profile already parsed from YAML (e.g. the copy a session keeps).

    ``source`` names the file in errors; ``key_prefix`` is the dotted key the profile
    sits under in that file (``"rig.values"`` in a session.yaml), so errors name it.
    """
    path = source
    top = KeyPath(path, key_prefix)
    keys = top.mapping(
        data,
        required=("version", "name", "baselines"),
        optional=(
            "camera", "cameras", "back_offset", "rangefinder", "notes", "nominal_range_m",
            "pipeline", "one_camera", "calibration",
        ),
    )
    _check_version(keys["version"], top.child("version"))
    baselines = top.child("baselines")
    pair = baselines.mapping(keys["baselines"], required=("C_lr", "C_lb"))
    cameras = _cameras(keys, top)
    one_camera = top.optional(keys, "one_camera", _one_camera) or False
    if one_camera and any(cameras[role] != cameras["left"] for role in CAMERA_ROLES):
        raise top.child("one_camera").error(
            "one camera took the three views, but `cameras:` gives them different specs "
            "(give one `camera:`)", True)
    return RigProfile(
        name=top.child("name").line(keys["name"]),
        cameras=cameras,
        baseline_lr=_baseline(pair["C_lr"], baselines.child("C_lr")),
        baseline_lb=_baseline(pair["C_lb"], baselines.child("C_lb")),
        back_offset_m=top.optional(keys, "back_offset", _back_offset),
        rangefinder=top.optional(keys, "rangefinder", _rangefinder),
        notes=top.child("notes").text(keys["notes"]) if "notes" in keys else "",
        nominal_range_m=top.optional(keys, "nominal_range_m", _nominal_range),
        source=path,
        pipeline=top.optional(keys, "pipeline", _pipeline) or {},
        one_camera=one_camera,
        calibration=top.optional(keys, "calibration", read_calibration),
    )


def _one_camera(value: Any, key: KeyPath) -> bool:
    if not isinstance(value, bool):
        raise key.error("must be true (one camera moved between the positions) or false "
                        "(three cameras)", value)
    return value


def read_rig_data(path: Path) -> Any:
    """A profile file's YAML as plain data, not yet checked (:func:`rig_from_data` does:
    ``rigkit depth --rig P --focal-px F`` puts its flags into it first)."""
    return read_strict_yaml(path, "rig profile")



def _check_version(value: Any, key: KeyPath) -> None:
    if isinstance(value, bool) or value != PROFILE_VERSION:
        raise key.error(f"unsupported profile version (this rigkit reads {PROFILE_VERSION})", value)


def _cameras(keys: dict[str, Any], top: KeyPath) -> Mapping[str, CameraSpec]:
    if ("camera" in keys) == ("cameras" in keys):
        raise top.error(
            "give either 'camera' (one spec shared by left, right and back) "
            "or 'cameras' (with left, right and back), not both or neither"
        )
    if "camera" in keys:
        shared = read_camera(keys["camera"], top.child("camera"))
        return MappingProxyType(dict.fromkeys(CAMERA_ROLES, shared))
    each = top.child("cameras")
    specs = each.mapping(keys["cameras"], required=CAMERA_ROLES)
    return MappingProxyType(
        {role: read_camera(specs[role], each.child(role)) for role in CAMERA_ROLES}
    )


def _baseline(value: Any, key: KeyPath) -> Baseline:
    keys = key.mapping(value, required=("value_m", "tolerance_m"))
    hint = "baselines are in metres; is this in centimetres or millimetres?"
    length = key.child("value_m").bounded(keys["value_m"], "m", _MAX_BASELINE_M,
                                          low=_MIN_BASELINE_M, hint=hint)
    tolerance_key = key.child("tolerance_m")
    tolerance = tolerance_key.number(keys["tolerance_m"], "m")
    if not 0.0 <= tolerance < length:
        raise tolerance_key.error(
            f"must be >= 0 and smaller than value_m ({length:g} m)", tolerance
        )
    return Baseline(value_m=length, tolerance_m=tolerance)


def _signed_offset(value: Any, key: KeyPath) -> float:
    number = key.number(value, "m")
    if abs(number) > _MAX_OFFSET_M:
        raise key.error(f"must be within +-{_MAX_OFFSET_M:g} m (is this in cm or mm?)", value)
    return number


def _back_offset(value: Any, key: KeyPath) -> tuple[float, float]:
    keys = key.mapping(value, required=("right_m", "up_m"))
    return (
        _signed_offset(keys["right_m"], key.child("right_m")),
        _signed_offset(keys["up_m"], key.child("up_m")),
    )


def _rangefinder(value: Any, key: KeyPath) -> RangefinderSpec:
    keys = key.mapping(value, required=("protocol",),
                       optional=("port", "baud", "offset", "max_range_m", "azimuth",
                                 "declination_deg"))
    protocol = keys["protocol"]
    if not isinstance(protocol, str) or not _PROTOCOL_PATTERN.fullmatch(protocol):
        raise key.child("protocol").error(
            "must be a lower-case name such as 'manual' (letters, digits, '-', '_')", protocol
        )
    port = key.child("port").line(keys["port"]) if "port" in keys else None
    baud = key.child("baud").integer(keys["baud"], "baud", _MAX_BAUD) if "baud" in keys else None
    if (port is None) != (baud is None):
        missing = "baud" if baud is None else "port"
        raise key.child(missing).error("missing: a serial rangefinder needs both port and baud")
    return RangefinderSpec(
        protocol=protocol,
        port=port,
        baud=baud,
        offset_m=key.optional(keys, "offset", _rangefinder_offset),
        max_range_m=key.optional(keys, "max_range_m", _max_range),
        **_azimuth_reference(keys, key),
    )


def _azimuth_reference(keys: dict[str, Any], key: KeyPath) -> dict[str, Any]:
    """``azimuth`` (true or magnetic) and the magnetic declination it needs."""
    azimuth = keys.get("azimuth", "true")
    if azimuth not in AZIMUTH_REFERENCES:
        raise key.child("azimuth").error("must be 'true' or 'magnetic'", azimuth)
    if "declination_deg" not in keys:
        if azimuth == "magnetic":
            raise key.child("declination_deg").error(
                "missing: magnetic azimuths need the local declination (degrees east of "
                "true north, negative west; e.g. from NOAA's declination calculator)")
        return {"azimuth": azimuth}
    declination = key.child("declination_deg").number(keys["declination_deg"], "degrees")
    if azimuth != "magnetic":
        raise key.child("declination_deg").error("applies to 'azimuth: magnetic' only",
                                                 declination)
    if not -180.0 <= declination <= 180.0:
        raise key.child("declination_deg").error("must be between -180 and 180 degrees",
                                                 declination)
    return {"azimuth": azimuth, "declination_deg": declination}


def _max_range(value: Any, key: KeyPath) -> float:
    return key.bounded(value, "m", MAX_RANGE_M, low=1.0)


def _rangefinder_offset(value: Any, key: KeyPath) -> tuple[float, float, float]:
    keys = key.mapping(value, required=("right_m", "up_m", "forward_m"))
    return (
        _signed_offset(keys["right_m"], key.child("right_m")),
        _signed_offset(keys["up_m"], key.child("up_m")),
        _signed_offset(keys["forward_m"], key.child("forward_m")),
    )


def _pipeline(value: Any, key: KeyPath) -> Mapping[str, float]:
    """Overrides of :class:`PipelineSettings`, checked by constructing them."""
    given = key.mapping(value, required=(), optional=setting_names())
    out: dict[str, float] = {}
    for name, v in given.items():
        number = key.child(name).number(v, "the setting's unit")
        if setting_type(name) is int and not float(number).is_integer():
            raise key.child(name).error("must be a whole number", v)
        out[name] = int(number) if setting_type(name) is int else number
    try:
        PipelineSettings(**out)  # type: ignore[arg-type]
    except ValueError as exc:
        raise key.error(str(exc)) from None
    return MappingProxyType(out)


def _nominal_range(value: Any, key: KeyPath) -> float:
    return key.bounded(value, "m", MAX_RANGE_M)


# --------------------------------------------------------------------------- writing


def rig_to_dict(profile: RigProfile) -> dict[str, Any]:
    """The profile as plain data in the YAML layout :func:`load_rig` reads."""
    data: dict[str, Any] = {"version": PROFILE_VERSION, "name": profile.name}
    if profile.nominal_range_m is not None:
        data["nominal_range_m"] = profile.nominal_range_m
    specs = [profile.cameras[role] for role in CAMERA_ROLES]
    if all(spec == specs[0] for spec in specs):
        data["camera"] = camera_to_dict(specs[0])
    else:
        data["cameras"] = {role: camera_to_dict(profile.cameras[role]) for role in CAMERA_ROLES}
    data["baselines"] = {
        "C_lr": _baseline_to_dict(profile.baseline_lr),
        "C_lb": _baseline_to_dict(profile.baseline_lb),
    }
    if profile.back_offset_m is not None:
        right, up = profile.back_offset_m
        data["back_offset"] = {"right_m": right, "up_m": up}
    if profile.rangefinder is not None:
        data["rangefinder"] = _rangefinder_to_dict(profile.rangefinder)
    if profile.notes:
        data["notes"] = profile.notes
    if profile.pipeline:
        data["pipeline"] = dict(profile.pipeline)
    if profile.one_camera:
        data["one_camera"] = True
    if profile.calibration is not None:
        data["calibration"] = calibration_to_dict(profile.calibration)
    return data


def dump_rig(profile: RigProfile) -> str:
    """The profile as YAML text that :func:`load_rig` reads back to an equal profile."""
    return dump_yaml(rig_to_dict(profile))


def _baseline_to_dict(baseline: Baseline) -> dict[str, float]:
    return {"value_m": baseline.value_m, "tolerance_m": baseline.tolerance_m}


def _rangefinder_to_dict(spec: RangefinderSpec) -> dict[str, Any]:
    data: dict[str, Any] = {"protocol": spec.protocol}
    if spec.port is not None:
        data["port"] = spec.port
        data["baud"] = spec.baud
    if spec.offset_m is not None:
        right, up, forward = spec.offset_m
        data["offset"] = {"right_m": right, "up_m": up, "forward_m": forward}
    if spec.max_range_m is not None:
        data["max_range_m"] = spec.max_range_m
    if spec.azimuth != "true":
        data["azimuth"] = spec.azimuth
        data["declination_deg"] = spec.declination_deg
    return data
