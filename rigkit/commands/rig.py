"""``rigkit rig``: work with rig profiles (``rigkit rig check PROFILE``)."""

from __future__ import annotations

import argparse
from pathlib import Path

from rigkit.commands import count, output_file, within
from rigkit.rig.defaults import (
    CRITICAL_W,
    DISPARITY_ERROR_PX,
    LASER_ACCURACY_M,
    MAX_RANGE_M,
    SHIMMER_PX,
)

DEFAULT_RANGE_M = 300.0
MIN_RANGE_M = 1.0
MAX_BUDGET_PX = 1000.0
"""The largest error, px, a budget takes (a disparity, the shimmer, the offset)."""
MAX_CORRELATION_PX = 1e6
"""The longest shimmer correlation a budget takes, px."""
MAX_LASER_SIGMA_M = 100.0
"""The largest one-sigma error of a laser reading a calibration takes, m."""

_RIG_EPILOG = """\
example:
  rigkit rig check rigs/p1000-tripod.yaml --range 250 --range 300

Profiles are described in docs/rig-profiles.md; rigs/ has examples.
"""

_CHECK_EPILOG = """\
examples:
  rigkit rig check rigs/p1000-tripod.yaml
  rigkit rig check rigs/vehicle-2m.yaml --range 200 --range 400 --json
  rigkit rig check rigs/p1000-tripod.yaml --capture L.NRW R.NRW B.NRW

exit status: 0 no warnings, 1 warnings printed, 2 bad profile, image or argument.
"""


def register(subparsers: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Add ``rig`` with its ``check`` subcommand."""
    parser = subparsers.add_parser(
        "rig",
        help="check a rig profile: focal length, FOV, error budget, capture EXIF",
        description="Work with rig profiles (YAML files describing the three cameras).",
        epilog=_RIG_EPILOG,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    sub = parser.add_subparsers(dest="rig_command", metavar="SUBCOMMAND", required=True)
    check = sub.add_parser(
        "check",
        help="print a profile's geometry and depth-error budget, and warn where it cannot work",
        description=(
            "Print the focal length in pixels, the field of view, the baseline/depth ratio\n"
            "and triangulation angle at the chosen ranges, and a depth-error budget over\n"
            "100-500 m; warn where the geometry cannot work. With --capture, also check\n"
            "three frames' EXIF against the profile and each other."
        ),
        epilog=_CHECK_EPILOG,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    check.add_argument("profile", metavar="PROFILE", type=Path, help="rig profile (YAML)")
    check.add_argument(
        "--range",
        dest="ranges",
        metavar="M",
        type=_range_m,
        action="append",
        help=f"a range to examine, metres; repeat for several (default: the profile's "
        f"nominal_range_m, else {DEFAULT_RANGE_M:g})",
    )
    check.add_argument(
        "--capture",
        nargs=3,
        metavar=("LEFT", "RIGHT", "BACK"),
        type=Path,
        help="three captured frames (RAW, JPEG or TIFF) whose EXIF to check",
    )
    check.add_argument(
        "--disparity-error-px",
        type=within(0.0, MAX_BUDGET_PX, "px"),
        default=DISPARITY_ERROR_PX,
        metavar="PX",
        help=f"disparity error for the budget (default {DISPARITY_ERROR_PX:g})",
    )
    check.add_argument(
        "--frames",
        type=count,
        default=1,
        metavar="N",
        help="frames per position (burst length) the offset's error is budgeted for (default 1)",
    )
    check.add_argument(
        "--shimmer-px",
        type=within(0.0, MAX_BUDGET_PX, "px"),
        metavar="PX",
        help="heat shimmer, px RMS per frame, the offset's error is budgeted for "
        "(default: moderate turbulence over 300 m, 6.8 µrad, in the profile's pixels: "
        f"{SHIMMER_PX:g} px at 6 deg across 4608 px)",
    )
    check.add_argument(
        "--shimmer-corr-px",
        type=within(0.0, MAX_CORRELATION_PX, "px", low_open=True),
        metavar="PX",
        help="the shimmer's correlation length, px, as `rigkit field` measures it "
        "(default: moderate air's 1.05 mrad in the profile's pixels, 46 px at 6 deg "
        "across 4608 px)",
    )
    check.add_argument(
        "--offset-error-px",
        type=within(0.0, MAX_BUDGET_PX, "px"),
        metavar="PX",
        help="error of the global disparity offset for the budget, instead of the one "
        "--frames, --shimmer-px and --shimmer-corr-px give",
    )
    check.add_argument("--json", action="store_true", help="print JSON instead of tables")
    check.set_defaults(runner="rigkit.commands.rig_run:run_check")
    _register_calibrate(sub)


_CALIBRATE_EPILOG = f"""\
examples:
  rigkit rig calibrate capture/ridge-0412 --out rigs/ridge-0412.yaml   # taped anew
  rigkit rig calibrate capture/van-* --out rigs/van-2026.yaml          # one fixed rig
  rigkit rig calibrate capture/van-1 --check-session capture/van-2 --out rigs/van.yaml
  rigkit rig calibrate capture/ridge-0412 --hold-out T5 --out rigs/ridge.yaml

Adjusts C_lb (the depth maps' scale), and f*C_lr where the targets determine it better
than the profile does, from each session's current run (process them first): every
target a row weighted by its laser accuracy and its window median's measured scatter,
the profile's tolerances rows too (the tape's, the lens spec's). A blunder (standardised
residual beyond {CRITICAL_W:g}) is named and left out; one that cannot be told from another row,
or a profile value beyond its tolerance, stops it (--beyond-tolerance lets the lasers
overrule the profile). Each target is checked by the fit without it and its twins;
held-out targets and check sessions only check it. Then: rigkit session set-rig SESSION
--rig OUT; rigkit process SESSION.
exit status: 0 written, 1 nothing better than the tape to write, 2 refused (nothing
written). docs/rig-profiles.md, "Calibrating the scale from the laser".
"""


def _register_calibrate(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    calibrate = sub.add_parser(
        "calibrate",
        help="fit the rig's scale (C_lb, f*C_lr) from sessions' laser targets",
        description="Write a rig profile whose C_lb (and f*C_lr, where the targets see it)\n"
                    "the sessions' laser targets fit, with the tolerances the fit leaves,\n"
                    "and a report of the adjustment like an instrument's calibration.",
        epilog=_CALIBRATE_EPILOG,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    calibrate.add_argument("sessions", metavar="SESSION", type=Path, nargs="+",
                           help="processed session folders of one rig")
    calibrate.add_argument("--out", type=output_file, required=True, help="the profile to write")
    calibrate.add_argument("--laser-sigma-m", type=within(0.0, MAX_LASER_SIGMA_M, "m",
                                                          low_open=True), metavar="M",
                           help="one laser reading's one-sigma error, m (default "
                                f"{LASER_ACCURACY_M:g})")
    calibrate.add_argument("--hold-out", action="append", default=[], metavar="TARGET",
                           help="a target (T3, or SESSION/T3) kept out of the fit and checked "
                                "against it (repeatable)")
    calibrate.add_argument("--check-session", action="append", default=[], type=Path,
                           metavar="SESSION",
                           help="a processed session of the same rig whose targets only "
                                "check the fit (repeatable)")
    calibrate.add_argument("--beyond-tolerance", action="store_true",
                           help="let the lasers overrule a profile value they find beyond "
                                "its tolerance (the tape was wrong) instead of refusing")
    calibrate.add_argument("--force", action="store_true",
                           help="replace --out, where it is a profile rigkit wrote")
    calibrate.set_defaults(runner="rigkit.commands.rig_run:run_calibrate")


_range_m = within(MIN_RANGE_M, MAX_RANGE_M, "m")
