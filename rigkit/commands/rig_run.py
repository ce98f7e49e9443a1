"""Running ``rigkit rig check`` and ``rig calibrate`` (their arguments:
:mod:`rigkit.commands.rig`)."""

from __future__ import annotations

import argparse
import json
from collections.abc import Sequence
from pathlib import Path

from rigkit.commands.rig import DEFAULT_RANGE_M
from rigkit.core.tables import visible
from rigkit.reporting.rig_check import format_check
from rigkit.rig import RigProfile, load_rig
from rigkit.rig.check import check_rig, check_to_dict
from rigkit.rig.findings import Finding


def run_calibrate(args: argparse.Namespace) -> int:
    """``rigkit rig calibrate``: 0 when the profile is written."""
    from rigkit.capture.session import check_outside
    from rigkit.core.files import check_writable_folder
    from rigkit.core.outputs import check_output_file, write_outputs
    from rigkit.errors import InputError
    from rigkit.reporting.scale import LASER_ACCURACY_M, format_calibration, sessions_targets
    from rigkit.rig.calibration import calibrated_profile, fit_scale
    from rigkit.rig.profile import dump_rig

    if args.out.suffix.lower() not in (".yaml", ".yml"):
        raise InputError(f"--out {args.out}: expected a .yaml file name for the profile")
    check_outside(args.out, args.sessions, f"--out {args.out}")
    check_output_file(args.out, "--out")  # --force replaces only a profile rigkit wrote
    if args.out.exists() and not args.force:
        raise InputError(f"{args.out}: exists; give --force to overwrite it")
    check_writable_folder(args.out.parent, f"--out {args.out}")
    accuracy = args.laser_sigma_m or LASER_ACCURACY_M
    profile, targets = sessions_targets(args.sessions, accuracy)
    fit = fit_scale(targets, profile)
    print(format_calibration(fit, profile, len(args.sessions)), end="")
    note = (f"Calibrated by rigkit rig calibrate from {len(fit.used)} laser target(s) in "
            f"{', '.join(str(s) for s in args.sessions)}: C_lb "
            f"{profile.baseline_lb.value_m:.4f} -> {profile.baseline_lb.value_m * fit.scale:.4f}"
            f" m" + ("" if fit.checked else " (unchecked: fewer than 3 targets)") + ".")
    write_outputs(args.out.parent, {args.out.name: dump_rig(calibrated_profile(profile, fit,
                                                                               note))}, "--out")
    print(f"wrote {args.out}; use it: rigkit session set-rig SESSION --rig {args.out}, "
          "then rigkit process SESSION")
    return 0


def run_check(args: argparse.Namespace) -> int:
    """``rigkit rig check``: 0 if nothing to warn about, 1 if warnings were printed."""
    profile = load_rig(args.profile)
    ranges = args.ranges or [profile.nominal_range_m or DEFAULT_RANGE_M]
    result = check_rig(
        profile,
        ranges,
        disparity_error_px=args.disparity_error_px,
        offset_error_px=args.offset_error_px,
        frames=args.frames,
        shimmer_px=args.shimmer_px,
        shimmer_corr_px=args.shimmer_corr_px,
        capture_findings=_capture_findings(profile, args.capture),
    )
    # EXIF text (a camera's model) is a file's: shown, never obeyed by the terminal
    print(json.dumps(check_to_dict(result), indent=2) if args.json
          else visible(format_check(result)))
    return 1 if result.findings else 0


def _capture_findings(profile: RigProfile, frames: Sequence[Path] | None) -> list[Finding]:
    if frames is None:
        return []
    from rigkit.capture.checks import check_capture, size_findings

    return check_capture(profile, frames) + size_findings(profile, frames)
