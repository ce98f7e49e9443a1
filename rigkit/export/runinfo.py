"""What an export knows of the run that made a depth map, read in this one place from the
run's metadata (a session's ``results/depth.json``, or ``rigkit depth``'s ``D.json``):
the run's id, time and rigkit version, the rig, the pipeline's settings and warnings, and
the lens the depth map lies on, through which every pixel is back-projected (the points
of ``rigkit export`` and the laser comparison of ``rigkit process`` alike).

The lens is the run's left view (:class:`rigkit.pipeline.lens.Lens`): its distortion
terms (``distortion_k1_k2_p1_p2_k3``, the lens the depth went through: fitted from the
views where the run fitted one, else the rig profile's), the centre of that distortion
(the fitted left centre, ``lens_fit.centres_px.left``, else the rig's left principal
point, ``rig.principal_points_px``) and the focal length. Metadata from before rigkit
recorded them falls back on the rig profile (a session's) or on ``left_camera_px`` (a
pinhole: f, cx, cy).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from rigkit.errors import InputError
from rigkit.geometry import NO_DISTORTION, distortion_coefficients
from rigkit.pipeline.lens import Lens
from rigkit.rig.profile import RigProfile


@dataclass(frozen=True)
class RunInfo:
    """A depth map's run. ``lens``: the left view's lens, (W, H) the depth map's size;
    ``lens_source``: where it comes from, in words; ``run_id``, ``time_utc``,
    ``rigkit_version``: None for a file that does not say; ``rig``: the rig profile's
    name; ``rig_values``: focal length and baselines as the run recorded them;
    ``settings``: the pipeline's settings (None: not recorded); ``warnings``: the run's;
    ``offset_depth_fraction``: the relative depth error the disparity offset alone
    leaves (one sigma, common to every pixel at a depth; None: not recorded)."""

    lens: Lens
    lens_source: str
    rig: str
    run_id: str | None = None
    time_utc: str | None = None
    rigkit_version: str | None = None
    rig_values: Mapping[str, Any] = field(default_factory=dict)
    settings: Mapping[str, Any] | None = None
    warnings: tuple[str, ...] = ()
    offset_depth_fraction: float | None = None

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready, for the export's metadata."""
        lens = self.lens
        return {
            "run_id": self.run_id, "time_utc": self.time_utc,
            "rigkit_version": self.rigkit_version, "rig": self.rig,
            "rig_values": dict(self.rig_values),
            "lens": {"focal_px": lens.focal_px, "size_px": list(lens.size),
                     "distortion_k1_k2_p1_p2_k3": list(lens.distortion),
                     "centre_shift_px": list(lens.shift), "source": self.lens_source},
            "settings": None if self.settings is None else dict(self.settings),
            "warnings": list(self.warnings),
            "offset_depth_error_fraction": self.offset_depth_fraction,
        }


def run_info(meta: Mapping[str, Any], size: tuple[int, int], where: Path | str,
             profile: RigProfile | None = None) -> RunInfo:
    """The run a depth map of ``size`` (W, H) px came from, from its metadata ``meta``
    (``where``: its file, for errors); ``profile``: the session's rig, for what older
    metadata does not say. InputError naming the key of a value that is not one."""
    reader = _Reader(meta, where)
    rig = reader.mapping("rig")
    lens, source = _lens(reader, rig, size, profile)
    name = rig.get("name", profile.name if profile is not None else None)
    if name is None:
        raise InputError(f"{where}: no rig focal length (not written by rigkit depth?)")
    values = {key: rig[key] for key in ("focal_px", "baseline_lr_m", "baseline_lb_m",
                                        "one_camera") if key in rig}
    offset = meta.get("offset_depth_error_fraction")
    return RunInfo(
        lens=lens, lens_source=source, rig=str(name),
        run_id=reader.text("run_id"), time_utc=reader.text("time_utc"),
        rigkit_version=reader.text("rigkit_version"), rig_values=values,
        settings=meta.get("settings") if isinstance(meta.get("settings"), dict) else None,
        warnings=tuple(str(w) for w in meta.get("warnings") or () if isinstance(w, str)),
        offset_depth_fraction=float(offset) if isinstance(offset, int | float) else None,
    )


def _lens(reader: _Reader, rig: Mapping[str, Any], size: tuple[int, int],
          profile: RigProfile | None) -> tuple[Lens, str]:
    """The left view's lens and where it comes from (see the module)."""
    geometry = profile.geometry() if profile is not None else None
    camera = reader.mapping("left_camera_px")
    focal = (reader.number(rig, "rig.focal_px") if "focal_px" in rig
             else geometry.focal_px if geometry is not None
             else reader.number(camera, "left_camera_px.f") if "f" in camera else None)
    if focal is None or focal <= 0:
        raise InputError(f"{reader.where}: no rig focal length (not written by rigkit depth?)")
    fit = reader.mapping("lens_fit")
    if "distortion_k1_k2_p1_p2_k3" in reader.meta:
        distortion = reader.numbers(reader.meta, "distortion_k1_k2_p1_p2_k3", 5)
    else:
        distortion = tuple(geometry.distortion) if geometry is not None else NO_DISTORTION
    centre = (size[0] - 1) / 2, (size[1] - 1) / 2
    if fit:
        shift = reader.numbers(reader.mapping("lens_fit.centres_px", fit), "lens_fit."
                               "centres_px.left", 2)
        source = "fitted from the three views by the run"
    elif "principal_points_px" in rig:
        shift = reader.numbers(reader.item(rig, "principal_points_px", 0),
                               "rig.principal_points_px[0]", 2)
        source = "the rig profile's"
    elif "cx" in camera and "cy" in camera:
        shift = (reader.number(camera, "left_camera_px.cx") - centre[0],
                 reader.number(camera, "left_camera_px.cy") - centre[1])
        source = "a pinhole at the recorded principal point (the run recorded no lens)"
    elif geometry is not None:
        shift = geometry.principal_points_px[0]
        source = "the rig profile's"
    else:
        shift = (0.0, 0.0)
        source = "a pinhole centred on the image (the run recorded no lens)"
    if not any(distortion) and not source.startswith("a pinhole"):
        source += ", without distortion"
    return Lens(focal, size, distortion_coefficients(distortion), (shift[0], shift[1])), source


@dataclass(frozen=True)
class _Reader:
    """Values of a metadata mapping, each checked, errors naming file and key."""

    meta: Mapping[str, Any]
    where: Path | str

    def mapping(self, key: str, inside: Mapping[str, Any] | None = None) -> Mapping[str, Any]:
        value = (self.meta if inside is None else inside).get(key.rsplit(".", 1)[-1])
        if value is None:
            return {}
        if not isinstance(value, Mapping):
            raise InputError(f"{self.where}: {key} is not a mapping")
        return value

    def item(self, inside: Mapping[str, Any], key: str, index: int) -> Any:
        value = inside.get(key)
        if not isinstance(value, list) or len(value) <= index:
            raise InputError(f"{self.where}: {key} is not a list of {index + 1} or more")
        return value[index]

    def number(self, inside: Mapping[str, Any], key: str) -> float:
        value = inside.get(key.rsplit(".", 1)[-1])
        if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(
                value):
            raise InputError(f"{self.where}: {key} is {value!r}, not a finite number")
        return float(value)

    def numbers(self, value: Any, key: str, count: int) -> tuple[float, ...]:
        if isinstance(value, Mapping):
            value = value.get(key.rsplit(".", 1)[-1])
        if (not isinstance(value, list) or len(value) != count
                or not all(isinstance(v, int | float) and not isinstance(v, bool)
                           and math.isfinite(v) for v in value)):
            raise InputError(f"{self.where}: {key} is {value!r}, not {count} finite numbers")
        return tuple(float(v) for v in value)

    def text(self, key: str) -> str | None:
        value = self.meta.get(key)
        return None if value is None else str(value)
