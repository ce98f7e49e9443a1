"""One camera of a rig profile: its spec, read from and written back to YAML.

The ``camera:`` (or each of ``cameras: left/right/back``) mapping of a profile
(docs/rig-profiles.md): model, sensor size, resolution, focal length in one of three
forms, principal point and lens distortion (OpenCV terms or a lensfun profile).
Errors name the file, the dotted key and the value (:class:`rigkit.core.yamlfile.KeyPath`).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from rigkit.core.yamlfile import KeyPath
from rigkit.errors import InputError
from rigkit.geometry import NO_DISTORTION, Distortion, distort
from rigkit.rig.lensfun import LensfunProfile, lensfun_profile
from rigkit.rig.optics import focal_px_from_35mm_equivalent, focal_px_from_mm, fov_deg

ASPECT_AGREEMENT = 0.01
"""``sensor_mm`` and ``resolution`` must have the same aspect ratio within 1 % (square pixels)."""
FOCAL_FORMS = ("mm", "equivalent_35mm_mm", "px")

_MAX_SENSOR_MM = 100.0
_MAX_FOCAL_MM = 5000.0
_MAX_EQUIVALENT_MM = 20000.0
_MAX_RESOLUTION_PX = 100_000
MAX_CORNER_SHIFT = 0.2
"""The most a lens's distortion may move the image corner, as a fraction of its distance
from the centre (fisheye lenses aside, lenses stay well under this)."""



@dataclass(frozen=True)
class CameraSpec:
    """One camera (left, right or back).

    ``focal_px`` is the pinhole focal length in pixels (fx = fy);
    ``focal_tolerance`` its relative uncertainty as a fraction (0.01 = 1 %);
    ``principal_point_px`` is (cx, cy) in pixels from the top-left pixel's corner,
    None meaning the image centre. ``focal_given`` keeps the form the profile used,
    e.g. ``("equivalent_35mm_mm", 400.0)``, so a profile is written back as it was read.
    """

    model: str
    sensor_mm: tuple[float, float] | None
    resolution: tuple[int, int]
    focal_px: float
    focal_tolerance: float
    principal_point_px: tuple[float, float] | None
    focal_given: tuple[str, float] | None = None
    distortion: Distortion = NO_DISTORTION
    lens_profile: LensfunProfile | None = None


@dataclass(frozen=True)
class Intrinsics:
    """A camera's pinhole model in the pixel convention of the depth maps, the pipeline
    and :mod:`rigkit.synth` (pixel centres at integers, the top-left one at (0, 0)):
    ``focal_px``; the principal point (``cx_px``, ``cy_px``), px; ``centre_offset_px``:
    that point's (x right, y down) offset from the image centre ((W - 1) / 2,
    (H - 1) / 2), px, as the pipeline takes it."""

    focal_px: float
    cx_px: float
    cy_px: float
    centre_offset_px: tuple[float, float]


def intrinsics(spec: CameraSpec, focal_px: float, image_size: tuple[int, int]) -> Intrinsics:
    """``spec``'s pinhole model for frames of ``image_size`` (W, H) px at ``focal_px``:
    the one conversion of a profile's ``principal_point_px`` (measured from the top-left
    pixel's corner, so less 0.5 px here), or the image centre where it gives none. The
    pipeline, the laser comparisons and export all take it from here."""
    width, height = image_size
    centre = ((width - 1) / 2, (height - 1) / 2)
    if spec.principal_point_px is None:
        cx, cy = centre
    else:
        cx, cy = spec.principal_point_px[0] - 0.5, spec.principal_point_px[1] - 0.5
    return Intrinsics(focal_px, cx, cy, (cx - centre[0], cy - centre[1]))


def read_camera(value: Any, key: KeyPath) -> CameraSpec:
    keys = key.mapping(
        value,
        required=("model", "resolution", "focal_length"),
        optional=("sensor_mm", "principal_point_px", "distortion"),
    )
    resolution = _resolution(keys["resolution"], key.child("resolution"))
    sensor = key.optional(keys, "sensor_mm", _sensor)
    if sensor is not None:
        _check_aspect(sensor, resolution, key)
    form, given, tolerance = _focal_length(keys["focal_length"], key.child("focal_length"))
    if form == "px":
        focal = given
    elif sensor is None:
        raise key.child("sensor_mm").error(f"missing: needed to convert focal_length.{form}")
    elif form == "mm":
        focal = focal_px_from_mm(given, sensor[0], resolution[0])
    else:
        focal = focal_px_from_35mm_equivalent(given, sensor, resolution)
    _check_field_of_view(focal, resolution[0], key.child("focal_length").child(form), given)
    principal = key.optional(keys, "principal_point_px", _principal_point)
    if principal is not None:
        _check_principal_point(principal, resolution, key.child("principal_point_px"))
    lens_profile = None
    if isinstance(keys.get("distortion"), dict) and "lensfun" in keys["distortion"]:
        lens_profile = _lensfun(
            keys["distortion"], key.child("distortion"), resolution, focal, sensor
        )
    spec = CameraSpec(
        model=key.child("model").line(keys["model"]),
        sensor_mm=sensor,
        resolution=resolution,
        focal_px=focal,
        focal_tolerance=tolerance,
        principal_point_px=principal,
        focal_given=(form, given),
        distortion=lens_profile.distortion
        if lens_profile
        else key.optional(keys, "distortion", _distortion) or NO_DISTORTION,
        lens_profile=lens_profile,
    )
    _check_corner_shift(spec, key.child("distortion"))
    return spec


def _check_corner_shift(spec: CameraSpec, key: KeyPath) -> None:
    """InputError when the distortion moves the image corner by more than
    ``MAX_CORNER_SHIFT`` of its distance from the centre: no lens does that (telephoto
    lenses: a few tenths of a percent to a few percent), so the terms are wrong (a
    value in other units, a typo such as 1e300)."""
    if spec.distortion == NO_DISTORTION:
        return
    width, height = spec.resolution
    x = np.array((width - 1) / 2 / spec.focal_px)
    y = np.array((height - 1) / 2 / spec.focal_px)
    with np.errstate(all="ignore"):
        xd, yd = distort(x, y, spec.distortion)
        shift = float(np.hypot(xd - x, yd - y) / np.hypot(x, y))
    if not shift <= MAX_CORNER_SHIFT:
        raise key.error(f"moves the image corner by {100 * shift:.3g} % of its distance from "
                        f"the centre; a lens moves it by at most {100 * MAX_CORNER_SHIFT:g} % "
                        "(terms in normalised image coordinates, OpenCV's model)",
                        list(spec.distortion))


def _resolution(value: Any, key: KeyPath) -> tuple[int, int]:
    width, height = key.pair(value, "width, height")
    return (
        key.integer(width, "pixels", _MAX_RESOLUTION_PX),
        key.integer(height, "pixels", _MAX_RESOLUTION_PX),
    )


def _sensor(value: Any, key: KeyPath) -> tuple[float, float]:
    width, height = key.pair(value, "width, height")
    hint = "sensor_mm is in millimetres; is this in micrometres or pixels?"
    return (
        key.bounded(width, "mm", _MAX_SENSOR_MM, hint=hint),
        key.bounded(height, "mm", _MAX_SENSOR_MM, hint=hint),
    )


def _check_aspect(sensor: tuple[float, float], resolution: tuple[int, int], key: KeyPath) -> None:
    sensor_aspect = sensor[0] / sensor[1]
    image_aspect = resolution[0] / resolution[1]
    if abs(sensor_aspect / image_aspect - 1.0) > ASPECT_AGREEMENT:
        suggested = sensor[0] * resolution[1] / resolution[0]
        raise key.child("sensor_mm").error(
            f"aspect {sensor_aspect:.4f} does not match resolution "
            f"{resolution[0]}x{resolution[1]} (aspect {image_aspect:.4f}); give the area the "
            f"image covers, e.g. [{sensor[0]:g}, {suggested:.5g}]",
            list(sensor),
        )


def _focal_length(value: Any, key: KeyPath) -> tuple[str, float, float]:
    """(form, value as given, tolerance fraction) read from a ``focal_length`` mapping."""
    keys = key.mapping(value, required=("tolerance_fraction",), optional=FOCAL_FORMS)
    forms = [form for form in FOCAL_FORMS if form in keys]
    if not forms:
        raise key.error(f"missing: give one of {', '.join(FOCAL_FORMS)}")
    if len(forms) > 1:
        raise key.error(
            f"give only one of {', '.join(FOCAL_FORMS)}", {form: keys[form] for form in forms}
        )
    form = forms[0]
    high = {"mm": _MAX_FOCAL_MM, "equivalent_35mm_mm": _MAX_EQUIVALENT_MM, "px": 1e7}[form]
    unit = "pixels" if form == "px" else "mm"
    given = key.child(form).bounded(keys[form], unit, high)
    return form, given, _tolerance_fraction(keys["tolerance_fraction"], key)


FOV_DEG = (0.01, 90.0)
"""The fields of view (degrees across the image's width) rigkit takes a camera to have.
Its method is for telephoto lenses (3-6 deg at the paper's protocol); outside these a
focal length is a mistake (one in mm given as px, a digit too many or too few), and the
pipeline's arithmetic on it overflowed or made an offset of 40 image widths."""


def _check_field_of_view(focal_px: float, width_px: int, key: KeyPath, given: float) -> None:
    fov = fov_deg(focal_px, width_px)
    low, high = FOV_DEG
    if not low <= fov <= high:
        raise key.error(f"gives a field of view of {fov:.3g} deg across {width_px} px; "
                        f"rigkit's cameras see {low:g}-{high:g} deg (a telephoto lens: "
                        "3-6 deg): check the value and its unit", given)


def _tolerance_fraction(value: Any, parent: KeyPath) -> float:
    key = parent.child("tolerance_fraction")
    number = key.number(value, "fraction")
    if not 0.0 <= number < 0.5:
        raise key.error("must be a fraction in [0, 0.5) -- 0.01 means 1 %", value)
    return number


def _principal_point(value: Any, key: KeyPath) -> tuple[float, float]:
    cx, cy = key.pair(value, "cx, cy")
    return key.number(cx, "pixels"), key.number(cy, "pixels")


def _check_principal_point(
    point: tuple[float, float], resolution: tuple[int, int], key: KeyPath
) -> None:
    if not (0 <= point[0] <= resolution[0] and 0 <= point[1] <= resolution[1]):
        raise key.error(f"must lie inside the {resolution[0]}x{resolution[1]} image", list(point))


DISTORTION_TERMS = ("k1", "k2", "p1", "p2", "k3")


def _distortion(value: Any, key: KeyPath) -> Distortion:
    """``{k1: .., k2: .., p1: .., p2: .., k3: ..}`` (any subset; OpenCV's model on
    normalised image coordinates about the image centre)."""
    terms = key.mapping(value, required=(), optional=DISTORTION_TERMS)
    k1, k2, p1, p2, k3 = (
        key.child(t).number(terms.get(t, 0.0), "normalised units") for t in DISTORTION_TERMS
    )
    return (k1, k2, p1, p2, k3)


def _lensfun(
    value: Any,
    key: KeyPath,
    resolution: tuple[int, int],
    focal_px: float,
    sensor: tuple[float, float] | None,
) -> LensfunProfile:
    """``{lensfun: CAMERA, lens: LENS, focal_mm: F}``: the distortion of lensfun's
    profile (``lens`` only for interchangeable lenses; ``focal_mm`` the real focal
    length, by default the profile's focal length over the sensor width)."""
    keys = key.mapping(value, required=("lensfun",), optional=("lens", "focal_mm"))
    if "focal_mm" in keys:
        focal_mm = key.child("focal_mm").bounded(keys["focal_mm"], "mm", _MAX_FOCAL_MM)
    elif sensor is not None:
        focal_mm = focal_px * sensor[0] / resolution[0]
    else:
        raise key.child("focal_mm").error(
            "missing: give the real focal length in mm (or camera.sensor_mm) to look the "
            "lens up"
        )
    lens = key.child("lens").line(keys["lens"]) if "lens" in keys else None
    camera = key.child("lensfun").line(keys["lensfun"])
    try:
        return lensfun_profile(camera, focal_mm, resolution, focal_px, lens)
    except InputError as exc:
        raise key.child("lensfun").error(str(exc)) from None


def camera_to_dict(spec: CameraSpec) -> dict[str, Any]:
    form, value = spec.focal_given or ("px", spec.focal_px)
    data: dict[str, Any] = {"model": spec.model}
    if spec.sensor_mm is not None:
        data["sensor_mm"] = list(spec.sensor_mm)
    data["resolution"] = list(spec.resolution)
    data["focal_length"] = {form: value, "tolerance_fraction": spec.focal_tolerance}
    if spec.principal_point_px is not None:
        data["principal_point_px"] = list(spec.principal_point_px)
    if spec.lens_profile is not None:
        lf = spec.lens_profile
        data["distortion"] = {"lensfun": lf.camera, "lens": lf.lens, "focal_mm": lf.focal_mm}
    elif spec.distortion != NO_DISTORTION:
        data["distortion"] = dict(zip(DISTORTION_TERMS, spec.distortion, strict=True))
    return data
