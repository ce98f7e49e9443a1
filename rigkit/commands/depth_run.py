"""Running ``rigkit depth`` (its arguments: :mod:`rigkit.commands.depth`)."""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path
from typing import Any

import numpy as np

from rigkit.batch.depthrun import DepthRun, run_depth
from rigkit.capture.frames import frame_files
from rigkit.capture.model import POSITIONS
from rigkit.capture.results import RunFiles
from rigkit.commands import parse_distortion
from rigkit.core.files import Content, check_not_inputs, check_writable_folder
from rigkit.core.outputs import check_outputs, write_outputs
from rigkit.core.progress import Progress
from rigkit.core.tables import visible
from rigkit.errors import InputError
from rigkit.imagefile.rawio import declared_size
from rigkit.reporting.previews import colorize, depth_range
from rigkit.rig.camera import DISTORTION_TERMS
from rigkit.rig.profile import RigProfile, read_rig_data, rig_from_data


def rig_profile(args: argparse.Namespace) -> RigProfile:
    """The rig: --rig's profile with the flags' values in place of its own, or (without
    --rig) the profile the flags describe for the size the left frame's header declares
    (:func:`flags_profile`). The flags go into the profile's data, which is then checked
    once, as a profile file is (:func:`rigkit.rig.profile.rig_from_data`)."""
    for flag, unit in (("focal_px", "pixels"), ("baseline_lr", "m"), ("baseline_lb", "m")):
        value = getattr(args, flag)
        if value is not None and not (math.isfinite(value) and value > 0):
            raise InputError(f"--{flag.replace('_', '-')} {value:g}: must be a positive "
                             f"number of {unit}")
    if args.rig is not None:
        return rig_from_data(_override(read_rig_data(args.rig), args), args.rig)
    missing = [flag for flag in ("focal_px", "baseline_lr", "baseline_lb")
               if getattr(args, flag) is None]
    if missing:
        raise InputError(
            "missing " + ", ".join("--" + m.replace("_", "-") for m in missing)
            + ": give --rig PROFILE or --focal-px, --baseline-lr and --baseline-lb"
        )
    return flags_profile(args, declared_size(args.left[0]))


def flags_profile(args: argparse.Namespace, size: tuple[int, int]) -> RigProfile:
    """The profile that --focal-px, --baseline-lr and --baseline-lb (and the lens flags)
    describe, for frames of ``size`` (W, H) px."""
    data = {
        "version": 1,
        "name": "command line",
        "camera": {"model": "as given on the command line", "resolution": list(size),
                   "focal_length": {"px": args.focal_px, "tolerance_fraction": 0.0}},
        "baselines": {name: {"value_m": value, "tolerance_m": 0.0} for name, value in
                      (("C_lr", args.baseline_lr), ("C_lb", args.baseline_lb))},
    }
    return rig_from_data(_override(data, args), Path("the command line"))


def _override(data: Any, args: argparse.Namespace) -> Any:
    """A profile's data with the command line's values in place of its own; where the
    data is not laid out as a profile, left for the check to name what is wrong."""
    if not isinstance(data, dict):
        return data
    shared, each = data.get("camera"), data.get("cameras")
    cameras = [shared] if isinstance(shared, dict) else \
        [c for c in each.values() if isinstance(c, dict)] if isinstance(each, dict) else []
    for camera in cameras:
        if args.focal_px is not None:
            given = camera.get("focal_length")
            tolerance = given.get("tolerance_fraction", 0.0) if isinstance(given, dict) else 0.0
            camera["focal_length"] = {"px": args.focal_px, "tolerance_fraction": tolerance}
        if args.distortion is not None:
            terms = parse_distortion(args.distortion)
            camera["distortion"] = dict(zip(DISTORTION_TERMS, terms, strict=True))
        if args.lensfun is not None:
            camera["distortion"] = _lensfun(args.lensfun)
    baselines = data.get("baselines")
    for name, value in (("C_lr", args.baseline_lr), ("C_lb", args.baseline_lb)):
        if value is not None and isinstance(baselines, dict):
            given = baselines.get(name)
            tolerance = given.get("tolerance_m", 0.0) if isinstance(given, dict) else 0.0
            baselines[name] = {"value_m": value, "tolerance_m": tolerance}
    if args.one_camera:
        data["one_camera"] = True
    if args.fixed_lens:
        pipeline = data.get("pipeline")
        data["pipeline"] = {**(pipeline if isinstance(pipeline, dict) else {}),
                            "distortion_terms": 0}
    return data


def _lensfun(text: str) -> dict[str, Any]:
    """``--lensfun CAMERA:FOCAL_MM`` as a profile's ``distortion`` mapping."""
    camera, _, focal = text.rpartition(":")
    try:
        return {"lensfun": camera, "focal_mm": float(focal)}
    except ValueError:
        raise InputError(f"--lensfun {text!r}: expected CAMERA:FOCAL_MM, e.g. "
                         "'Coolpix P1000:71.9'") from None


def run(args: argparse.Namespace) -> int:
    missing = [f"no {pos} frame" for pos in POSITIONS if not getattr(args, pos)]
    if missing:
        raise InputError("; ".join(missing))
    if args.out.suffix != ".npy":
        raise InputError(f"--out {args.out}: expected a .npy file name")
    check_writable_folder(args.out.parent, f"--out {args.out}")
    names = [path.name for path in _output_paths(args.out, args.preview)]
    check_outputs(args.out.parent, names, "--out", "depth")  # the files written beside it too
    rig = rig_profile(args)
    bursts = frame_files({pos: getattr(args, pos) for pos in POSITIONS})
    read = [frame.path for frames in bursts.values() for frame in frames]
    check_not_inputs([args.out.parent / name for name in names],
                     read + ([args.rig] if args.rig is not None else []), f"--out {args.out}")
    size_from = None if args.rig is not None else f"the left frame {args.left[0]} is"
    task = args.left[0].name
    with Progress("depth", [task], quiet=args.quiet) as progress:
        run = run_depth(bursts, rig, force=args.force, size_from=size_from,
                        progress=lambda stage, f: progress.update(task, f, stage))
    write_outputs(args.out.parent, _outputs(run, args.out, args.preview), "--out", "depth")
    print(_summary(run, args.out))
    for warning in run.warnings:
        print(f"warning: {visible(warning, lines=False)}", file=sys.stderr)
    return 0


def _previews(out: Path) -> tuple[Path, Path]:
    """``--preview``'s files beside OUT: the colour-mapped depth and sigma."""
    return out.with_suffix(".png"), out.with_suffix(".sigma.png")


def _output_paths(out: Path, preview: bool) -> list[Path]:
    """Every file ``rigkit depth --out OUT`` writes."""
    files = RunFiles.beside(out)
    made = [files.depth, files.sigma, files.record, files.grey, files.flags]
    return made + (list(_previews(out)) if preview else [])


def _outputs(run: DepthRun, out: Path, preview: bool) -> dict[str, Content]:
    contents = run.outputs(RunFiles.beside(out), run.record())
    if preview:
        result = run.result
        lo, hi = depth_range(result.depth)
        depth_png, sigma_png = _previews(out)
        contents[depth_png.name] = colorize(result.depth, lo, hi, "depth z (m)")
        contents[sigma_png.name] = colorize(100 * result.sigma / result.depth, 0.0, 2.0,
                                            "1-sigma error (% of depth)")
    return contents


def _summary(run: DepthRun, out: Path) -> str:
    result = run.result
    a, lens = result.ambiguity, result.lens_fit
    fitted = ""
    if lens is not None:
        taken = "" if lens.significant else ", not taken"
        fitted = f", lens corner {lens.corner_px:+.2f} +- {lens.corner_sigma_px:.2f} px{taken}"
    height, width = result.depth.shape
    return (
        f"wrote {out} ({width}x{height}, "
        f"density {100 * float(np.isfinite(result.depth).mean()):.1f} %, "
        f"median depth {result.median_depth_m:.1f} m, "
        f"offset {a.offset_px:.2f} +- {a.offset_sigma_px:.2f} px{fitted}, "
        f"{sum(result.timings_s.values()):.1f} s)"
    )
