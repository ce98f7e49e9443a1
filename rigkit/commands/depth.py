"""``rigkit depth``: dense metric depth of the left view from three images."""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path
from typing import Any

POSITIONS = ("left", "right", "back")

EXAMPLE = """examples:
  rigkit depth left.NRW right.NRW back.NRW --rig rigs/p1000-tripod.yaml --out out/depth.npy

  rigkit synth out/scene --seed 7 --width 1152 --height 864      # a scene to try it on
  rigkit depth out/scene/left.png out/scene/right.png out/scene/back.png --focal-px 10990.73 \\
      --baseline-lr 2 --baseline-lb 2 --out out/scene-depth.npy --preview
  rigkit eval out/scene --depth-dir out                                # its accuracy

  rigkit depth capture/example/raw/left.png,capture/example/raw/left-2.png,\\
capture/example/raw/left-3.png capture/example/raw/right.png,capture/example/raw/right-2.png,\\
capture/example/raw/right-3.png capture/example/raw/back.png,capture/example/raw/back-2.png,\\
capture/example/raw/back-3.png --rig capture/example/rig.yaml --out out/burst.npy
                                # bursts: aligned and median-stacked per position

Frames are read as `rigkit process` reads a session's: RAW files through LibRaw at full
size (never an embedded preview), every frame checked for a picture and, with --rig, for
the profile's image size. Writes DEPTH.npy ((H, W) float32, metres, z in the left camera,
NaN = no estimate, in the original left image's pixel grid), DEPTH.sigma.npy (one
standard error, metres), DEPTH.json (frames, rig, warnings, offset, matches, timings),
DEPTH.grey.png (the left image as the pipeline saw it, 8-bit, for `rigkit export`),
DEPTH.flags.npy (what each pixel's depth rests on, uint8 bits: 1 matched, 2 filled, 4 nothing
to match, 8 the views disagree: something moved between the captures) and with
--preview DEPTH.png and DEPTH.sigma.png. Outputs appear together or not at all.
"""


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "depth",
        help="dense metric depth of the left view from left, right and back images",
        description="Pseudo-rectify left/right, match stereo, remove the disparity offset "
        "with the back view, and triangulate metric depth (docs/pipeline.md).",
        epilog=EXAMPLE,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("left", type=_frames,
                   help="left frame (RAW such as NEF/NRW/DNG/CR2/CR3, or PNG, TIFF, JPEG), or "
                   "a burst as a.png,b.png,... (aligned and median-stacked against heat "
                   "shimmer)")
    p.add_argument("right", type=_frames, help="right frame or burst, same size")
    p.add_argument("back", type=_frames, help="back frame or burst, same size")
    p.add_argument("--rig", type=Path, help="rig profile YAML (gives f, both baselines, the "
                   "lens and the image size every frame must have)")
    p.add_argument("--focal-px", type=float, help="focal length, px (overrides --rig)")
    p.add_argument("--baseline-lr", type=float, help="left-right baseline C_lr, m")
    p.add_argument("--baseline-lb", type=float, help="left-back distance C_lb along z, m")
    p.add_argument("--distortion", metavar="K1[,K2[,P1,P2[,K3]]]",
                   help="lens distortion, OpenCV model on normalised coordinates about the "
                   "image centre (overrides --rig's camera.distortion)")
    p.add_argument("--lensfun", metavar="CAMERA:FOCAL_MM",
                   help="lens distortion from lensfun's profile of CAMERA's built-in lens at "
                   "the real focal length FOCAL_MM, e.g. 'Coolpix P1000:71.9'")
    p.add_argument("--fixed-lens", action="store_true",
                   help="use the given distortion as it is (default: refine it, or fit it "
                   "when none is given, from the three views)")
    p.add_argument("--force", action="store_true",
                   help="compute depth even where the frames' EXIF focal length contradicts "
                   "the rig profile")
    p.add_argument("--out", type=Path, required=True, help="depth map to write (.npy)")
    p.add_argument("--preview", action="store_true", help="also write colour-mapped PNGs")
    p.add_argument("--quiet", action="store_true", help="no progress output")
    p.set_defaults(func=run)


def _frames(text: str) -> list[Path]:
    """One file, or the frames of a burst separated by commas."""
    return [Path(p) for p in text.split(",") if p]


def rig_source(args: argparse.Namespace) -> Any:  # RigProfile | (size -> RigProfile)
    """The rig: --rig's profile with the flags' values in place of its own, or (without
    --rig) a function giving the profile that the flags describe for the frames' size.
    Both are checked as a profile file is (:func:`rigkit.rig.profile.rig_from_data`)."""
    from rigkit.errors import InputError
    from rigkit.rig.profile import load_rig, rig_from_data, rig_to_dict

    for flag, unit in (("focal_px", "pixels"), ("baseline_lr", "m"), ("baseline_lb", "m")):
        value = getattr(args, flag)
        if value is not None and not (math.isfinite(value) and value > 0):
            raise InputError(f"--{flag.replace('_', '-')} {value:g}: must be a positive "
                             f"number of {unit}")
    if args.rig is not None:
        profile = load_rig(args.rig)
        return rig_from_data(_override(rig_to_dict(profile), args), args.rig)
    missing = [flag for flag in ("focal_px", "baseline_lr", "baseline_lb")
               if getattr(args, flag) is None]
    if missing:
        raise InputError(
            "missing " + ", ".join("--" + m.replace("_", "-") for m in missing)
            + ": give --rig PROFILE or --focal-px, --baseline-lr and --baseline-lb"
        )

    def at_size(size: tuple[int, int]) -> Any:
        data = {
            "version": 1,
            "name": "command line",
            "camera": {"model": "as given on the command line", "resolution": list(size),
                       "focal_length": {"px": args.focal_px, "tolerance_fraction": 0.0}},
            "baselines": {name: {"value_m": value, "tolerance_m": 0.0} for name, value in
                          (("C_lr", args.baseline_lr), ("C_lb", args.baseline_lb))},
        }
        return rig_from_data(_override(data, args), Path("the command line"))

    return at_size


def _override(data: dict[str, Any], args: argparse.Namespace) -> dict[str, Any]:
    """Profile data with the command line's values in place of its own."""
    from rigkit.commands import parse_distortion
    from rigkit.rig.camera import DISTORTION_TERMS

    cameras = [data["camera"]] if "camera" in data else list(data["cameras"].values())
    for camera in cameras:
        if args.focal_px is not None:
            tolerance = camera["focal_length"]["tolerance_fraction"]
            camera["focal_length"] = {"px": args.focal_px, "tolerance_fraction": tolerance}
        if args.distortion is not None:
            terms = parse_distortion(args.distortion)
            camera["distortion"] = dict(zip(DISTORTION_TERMS, terms, strict=True))
        if args.lensfun is not None:
            camera["distortion"] = _lensfun(args.lensfun)
    for name, value in (("C_lr", args.baseline_lr), ("C_lb", args.baseline_lb)):
        if value is not None:
            data["baselines"][name]["value_m"] = value
    if args.fixed_lens:
        data["pipeline"] = {**data.get("pipeline", {}), "distortion_terms": 0}
    return data


def _lensfun(text: str) -> dict[str, Any]:
    """``--lensfun CAMERA:FOCAL_MM`` as a profile's ``distortion`` mapping."""
    from rigkit.errors import InputError

    camera, _, focal = text.rpartition(":")
    try:
        return {"lensfun": camera, "focal_mm": float(focal)}
    except ValueError:
        raise InputError(f"--lensfun {text!r}: expected CAMERA:FOCAL_MM, e.g. "
                         "'Coolpix P1000:71.9'") from None


def run(args: argparse.Namespace) -> int:
    from rigkit.batch.depthrun import run_depth
    from rigkit.capture.frames import frame_files
    from rigkit.core.files import check_writable_folder, write_together
    from rigkit.core.progress import Progress
    from rigkit.errors import InputError

    if args.out.suffix != ".npy":
        raise InputError(f"--out {args.out}: expected a .npy file name")
    if args.out.is_dir():
        raise InputError(f"--out {args.out}: a folder; give a file name such as depth.npy")
    check_writable_folder(args.out.parent, f"--out {args.out}")
    rig = rig_source(args)
    bursts = frame_files({pos: getattr(args, pos) for pos in POSITIONS})
    task = args.left[0].name
    with Progress("depth", [task], quiet=args.quiet) as progress:
        run = run_depth(bursts, rig, force=args.force,
                        progress=lambda stage, f: progress.update(task, f, stage))
    write_together(args.out.parent, _outputs(run, args.out, args.preview))
    print(_summary(run, args.out))
    for warning in run.warnings:
        print(f"warning: {warning}", file=sys.stderr)
    return 0


def _outputs(run: Any, out: Path, preview: bool) -> dict[str, Any]:
    import json

    from rigkit.reporting.previews import colorize, depth_range

    result = run.result
    files: dict[str, Any] = {
        out.name: result.depth,
        f"{out.stem}.sigma.npy": result.sigma,
        f"{out.stem}.json": json.dumps(run.metadata(), indent=2),
        f"{out.stem}.grey.png": run.left_grey(),
        f"{out.stem}.flags.npy": result.flags(),
    }
    if preview:
        lo, hi = depth_range(result.depth)
        files[f"{out.stem}.png"] = colorize(result.depth, lo, hi, "depth z (m)")
        files[f"{out.stem}.sigma.png"] = colorize(100 * result.sigma / result.depth, 0.0, 2.0,
                                                  "1-sigma error (% of depth)")
    return files


def _summary(run: Any, out: Path) -> str:
    import numpy as np

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
