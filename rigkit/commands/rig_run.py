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
    """``rigkit rig calibrate``: 0 when the profile is written, 1 where the lasers know
    nothing better than the tape (nothing written)."""
    from rigkit.capture.session import check_outside
    from rigkit.core.files import check_creatable
    from rigkit.core.outputs import check_output_file, write_outputs
    from rigkit.errors import InputError
    from rigkit.reporting.calibration_report import calibration_record, format_calibration
    from rigkit.reporting.scale import plain, read_sessions
    from rigkit.rig.calibrated import calibrated_profile
    from rigkit.rig.calibration import fit_scale
    from rigkit.rig.defaults import LASER_ACCURACY_M
    from rigkit.rig.profile import dump_rig

    out = args.out
    what = f"--out {plain(str(out))}"
    if out.suffix.lower() not in (".yaml", ".yml"):
        raise InputError(f"{what}: expected a .yaml file name for the profile")
    check_outside(out, [*args.sessions, *args.check_session], what)
    check_output_file(out, "--out", "profile")  # --force replaces only a profile rigkit wrote
    check_creatable(out, what)
    if out.exists() and not args.force:
        raise InputError(f"{plain(str(out))}: exists; give --force to overwrite it")
    given = read_sessions(args.sessions, args.check_session, args.hold_out,
                          args.laser_sigma_m or LASER_ACCURACY_M)
    fit = fit_scale(given.targets, given.profile, held_out=given.held_out,
                    overrule=args.beyond_tolerance)
    written = calibrated_profile(given.profile, fit, calibration_record(fit, given))
    print(format_calibration(fit, given, written.changes, written.kept), end="")
    if not written.changes:
        print("nothing written: the lasers know the scale no better than the profile does")
        return 1
    try:
        out.parent.mkdir(parents=True, exist_ok=True)
        write_outputs(out.parent, {out.name: dump_rig(written.profile)}, "--out", "profile")
    except OSError as exc:
        raise InputError(f"{what}: cannot write the profile ({exc.strerror})") from None
    print(f"wrote {plain(str(out))} ({plain(written.profile.name)}); use it: rigkit session "
          f"set-rig SESSION --rig {plain(str(out))}, then rigkit process SESSION")
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
