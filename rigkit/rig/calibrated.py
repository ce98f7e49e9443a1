"""The profile a calibration gives (:mod:`rigkit.rig.calibration`): C_lb, and f and
C_lr where fitted, as the lasers say with their sigmas as tolerances, the laser's
additive constant in the rangefinder's offset where the targets determine it, the
provenance block and a name that says the profile is calibrated.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

from rigkit.rig.calibration import UNSTATED_TOLERANCE, ScaleFit, shape_tolerances
from rigkit.rig.profile import Baseline, RangefinderSpec, RigProfile
from rigkit.rig.provenance import Calibration


@dataclass(frozen=True)
class CalibratedValues:
    """What a calibration changes in a profile and why: ``profile`` the new one,
    ``changes`` one line per value that changed (before -> after), ``kept`` one line per
    value the fit would have made worse for other captures (the tape kept)."""

    profile: RigProfile
    changes: tuple[str, ...]
    kept: tuple[str, ...]


def calibrated_profile(profile: RigProfile, fit: ScaleFit, record: Calibration
                       ) -> CalibratedValues:
    """``profile`` with C_lb (and, where fitted, f and C_lr) as the lasers say, their
    tolerances one sigma of the fit, ``record`` as its provenance and a name that says
    it is calibrated. C_lb stays the tape's where the fit knows it no better for other
    captures than the tape does. An error in f * C_lr is shared between f and C_lr in
    proportion to their prior variances (the lasers cannot tell them apart)."""
    lb = profile.baseline_lb
    changes: list[str] = []
    kept: list[str] = []
    tape = lb.relative_tolerance or UNSTATED_TOLERANCE
    baseline_lb = lb
    if fit.scale_sigma < tape:
        baseline_lb = Baseline(lb.value_m * fit.scale, lb.value_m * fit.scale_sigma)
        changes.append(f"C_lb {lb.value_m:.4f} +- {lb.tolerance_m:.4f} m -> "
                       f"{baseline_lb.value_m:.4f} +- {baseline_lb.tolerance_m:.4f} m")
    else:
        kept.append(f"C_lb kept at the tape's {lb.value_m:.4f} +- {lb.tolerance_m:.4f} m: "
                    f"the lasers know it to +-{100 * fit.scale_sigma:.2f} % for other "
                    f"captures, no better than the tape's +-{100 * tape:.2f} %")
    cameras, baseline_lr = dict(profile.cameras), profile.baseline_lr
    if fit.shape_fitted:
        tol_f, tol_c = shape_tolerances(profile)
        share = tol_f**2 / (tol_f**2 + tol_c**2)
        f_factor, c_factor = fit.shape**share, fit.shape ** (1 - share)
        before_f, before_tol = profile.focal_px, profile.focal_tolerance
        for role, camera in cameras.items():
            focal = camera.focal_px * f_factor
            cameras[role] = replace(camera, focal_px=focal, focal_given=("px", focal),
                                    focal_tolerance=fit.shape_sigma * math.sqrt(share))
        baseline_lr = Baseline(baseline_lr.value_m * c_factor,
                               baseline_lr.value_m * c_factor * fit.shape_sigma
                               * math.sqrt(1 - share))
        changes.append(f"f {before_f:.1f} px +- {100 * before_tol:.2f} % -> "
                       f"{before_f * f_factor:.1f} px +- "
                       f"{100 * fit.shape_sigma * math.sqrt(share):.2f} %")
        lr = profile.baseline_lr
        changes.append(f"C_lr {lr.value_m:.4f} +- {lr.tolerance_m:.4f} m -> "
                       f"{baseline_lr.value_m:.4f} +- {baseline_lr.tolerance_m:.4f} m")
    rangefinder = _rangefinder(profile, fit, changes, kept)
    out = replace(profile, name=calibrated_name(profile.name, record.date_utc),
                  cameras=cameras, baseline_lr=baseline_lr, baseline_lb=baseline_lb,
                  rangefinder=rangefinder,
                  calibration=replace(record, changes=tuple(changes + kept)))
    return CalibratedValues(out, tuple(changes), tuple(kept))


MAX_LASER_OFFSET_M = 10.0
"""The largest rangefinder offset a profile takes (rig.profile's bound), m."""


def _rangefinder(profile: RigProfile, fit: ScaleFit, changes: list[str], kept: list[str]
                 ) -> RangefinderSpec | None:
    """The profile's rangefinder with the laser's additive constant, where the targets
    determine it, taken into its forward offset: a laser reading c long ranges from an
    aperture c behind where the profile put it."""
    spec = profile.rangefinder
    if not fit.laser_constant_seen:
        return spec
    c, sigma = fit.laser_constant_m
    spec = spec or RangefinderSpec("manual", None, None, None)
    right, up, forward = spec.offset_m or (0.0, 0.0, 0.0)
    if abs(forward - c) > MAX_LASER_OFFSET_M:
        kept.append(f"the laser's additive constant {c:+.2f} +- {sigma:.2f} m not written: "
                    f"it would put the rangefinder {forward - c:+.1f} m forward")
        return profile.rangefinder
    changes.append(f"rangefinder forward offset {forward:+.3f} m -> {forward - c:+.3f} m (the "
                   f"laser's additive constant {c:+.2f} +- {sigma:.2f} m)")
    return replace(spec, offset_m=(right, up, forward - c))


def calibrated_name(name: str, date_utc: str) -> str:
    """A profile's name once calibrated: its base (without ``-taped`` or an earlier
    calibration's suffix) and ``-laser-calibrated-YYYYMMDD``."""
    base = name.strip()
    for suffix in ("-taped", "_taped", " taped"):
        if base.lower().endswith(suffix):
            base = base[: -len(suffix)]
    marker = base.lower().rfind("-laser-calibrated-")
    if marker > 0:
        base = base[:marker]
    day = "".join(ch for ch in date_utc[:10] if ch.isdigit())
    return f"{base}-laser-calibrated-{day}"
