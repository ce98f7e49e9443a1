"""``rigkit depth``: dense metric depth of the left view from three images."""

from __future__ import annotations

import argparse
import json
import sys
from dataclasses import replace
from pathlib import Path

POSITIONS = ("left", "right", "back")

EXAMPLE = """example:
  rigkit depth left.png right.png back.png --focal-px 43963 --baseline-lr 2 --baseline-lb 2 \\
      --out out/depth.npy --preview
  rigkit depth capture/example/left.png capture/example/right.png capture/example/back.png \\
      --rig rigs/example.yaml --out out/example.npy --preview

  rigkit depth l1.png,l2.png,l3.png r1.png,r2.png,r3.png b1.png,b2.png,b3.png --rig RIG \\
      --out out/burst.npy                  # bursts: aligned and median-stacked per position

writes DEPTH.npy ((H, W) float32, metres, z in the left camera, NaN = no estimate, in the
original left image's pixel grid), DEPTH.sigma.npy (one standard error, metres),
DEPTH.json (offset, matches, warps, timings) and with --preview DEPTH.png and
DEPTH.sigma.png. Outputs appear together or not at all.
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
                   help="left image (PNG, TIFF or JPEG; 8/16-bit), or a burst as "
                   "a.png,b.png,... (aligned and median-stacked against heat shimmer)")
    p.add_argument("right", type=_frames, help="right image or burst, same size")
    p.add_argument("back", type=_frames, help="back image or burst, same size")
    p.add_argument("--rig", type=Path, help="rig profile YAML (gives f and both baselines)")
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
    p.add_argument("--out", type=Path, required=True, help="depth map to write (.npy)")
    p.add_argument("--preview", action="store_true", help="also write colour-mapped PNGs")
    p.add_argument("--quiet", action="store_true", help="no progress output")
    p.set_defaults(func=run)


def _frames(text: str) -> list[Path]:
    """One file, or the frames of a burst separated by commas."""
    return [Path(p) for p in text.split(",") if p]


def load_position(paths: list[Path], position: str, measure: bool):
    """The image of one position: the file, or its burst stacked; and, if ``measure``,
    the heat shimmer between the burst's first two frames (None for a single frame;
    :func:`rigkit.pipeline.shimmer.burst_shimmer`)."""
    from rigkit.pipeline.burst import stack_burst
    from rigkit.pipeline.images import load_grey
    from rigkit.pipeline.shimmer import burst_shimmer

    frames = [load_grey(p) for p in paths]
    shimmer = burst_shimmer(frames, position) if measure else None
    return stack_burst(frames, f"{position} burst"), shimmer


def rig_geometry(args: argparse.Namespace):  # -> (RigGeometry, PipelineSettings)
    """f, baselines and lens from --rig, overridden by explicit flags (f and both
    baselines required); the pipeline settings from --rig's ``pipeline:`` section."""
    from dataclasses import asdict

    from rigkit.commands import parse_distortion
    from rigkit.errors import InputError
    from rigkit.pipeline import RigGeometry
    from rigkit.pipeline.settings import PipelineSettings

    values: dict[str, object] = {
        "focal_px": None,
        "baseline_lr_m": None,
        "baseline_lb_m": None,
    }
    settings = PipelineSettings()
    if args.rig is not None:
        from rigkit.rig import load_rig

        profile = load_rig(args.rig)
        values = asdict(profile.geometry())
        settings = profile.pipeline_settings()
    if args.distortion is not None:
        values["distortion"] = parse_distortion(args.distortion)
    for key, flag in (
        ("focal_px", "focal_px"),
        ("baseline_lr_m", "baseline_lr"),
        ("baseline_lb_m", "baseline_lb"),
    ):
        if getattr(args, flag) is not None:
            values[key] = getattr(args, flag)
    missing = [k for k, v in values.items() if v is None]
    if missing:
        raise InputError(
            "missing " + ", ".join(missing) + ": give --rig PROFILE or "
            "--focal-px, --baseline-lr and --baseline-lb"
        )
    return RigGeometry(**values), settings  # type: ignore[arg-type]


def run(args: argparse.Namespace) -> int:
    import numpy as np

    from rigkit.core.files import write_together
    from rigkit.core.progress import Progress
    from rigkit.errors import InputError
    from rigkit.pipeline import estimate_depth
    from rigkit.reporting.previews import colorize, depth_range
    from rigkit.rig.budget import burst_warning

    rig, settings = rig_geometry(args)
    if args.out.suffix != ".npy":
        raise InputError(f"--out {args.out}: expected a .npy file name")
    images, shimmer = [], None
    for position in POSITIONS:
        image, found = load_position(getattr(args, position), position, shimmer is None)
        images.append(image)
        shimmer = shimmer or found
    left, right, back = images
    if args.lensfun:
        rig = replace(rig, distortion=_lensfun(args.lensfun, rig.focal_px, left.shape))
    if args.fixed_lens:
        settings = replace(settings, distortion_terms=0)
    task = args.left[0].name
    with Progress("depth", [task], quiet=args.quiet) as progress:
        result = estimate_depth(
            left, right, back, rig, progress=lambda stage, f: progress.update(task, f, stage),
            settings=settings,
        )

    out = args.out
    out.parent.mkdir(parents=True, exist_ok=True)
    stem = out.stem
    files: dict[str, str | np.ndarray] = {
        out.name: result.depth,
        f"{stem}.sigma.npy": result.sigma,
    }
    meta = {
        "inputs": {k: [str(p) for p in getattr(args, k)] for k in ("left", "right", "back")},
        "rig": {
            "focal_px": rig.focal_px,
            "baseline_lr_m": rig.baseline_lr_m,
            "baseline_lb_m": rig.baseline_lb_m,
            "distortion_k1_k2_p1_p2_k3": list(rig.distortion),
        },
        "shimmer": {"frames": shimmer[1], **shimmer[0].as_dict()} if shimmer else None,
        **result.diagnostics(),
    }
    files[f"{stem}.json"] = json.dumps(meta, indent=2)
    if args.preview:
        lo, hi = depth_range(result.depth)
        files[f"{stem}.png"] = colorize(result.depth, lo, hi, "depth z (m)")
        rel = 100 * result.sigma / result.depth
        files[f"{stem}.sigma.png"] = colorize(rel, 0.0, 2.0, "1-sigma error (% of depth)")
    write_together(out.parent, files)
    a, lens = result.ambiguity, result.lens_fit
    fitted = ""
    if lens is not None:
        taken = "" if lens.significant else ", not taken"
        fitted = f", lens corner {lens.corner_px:+.2f} +- {lens.corner_sigma_px:.2f} px{taken}"
    print(
        f"wrote {out} ({left.shape[1]}x{left.shape[0]}, "
        f"density {100 * float(np.isfinite(result.depth).mean()):.1f} %, "
        f"median depth {result.median_depth_m:.1f} m, "
        f"offset {a.offset_px:.2f} +- {a.offset_sigma_px:.2f} px{fitted}, "
        f"{sum(result.timings_s.values()):.1f} s)"
    )
    warnings = [result.offset_warning()]
    if shimmer is not None:
        measured, where = shimmer
        frames = min(len(getattr(args, p)) for p in POSITIONS)
        warnings.append(burst_warning(measured, where, (left.shape[1], left.shape[0]),
                                      rig.focal_px, rig.baseline_lr_m, result.median_depth_m,
                                      frames))
    for warning in filter(None, warnings):
        print(f"warning: {warning}", file=sys.stderr)
    return 0


def _lensfun(text: str, focal_px: float, shape: tuple[int, ...]):  # -> Distortion
    """``--lensfun CAMERA:FOCAL_MM`` converted for these images."""
    from rigkit.errors import InputError
    from rigkit.rig.lensfun import lensfun_profile

    camera, _, focal = text.rpartition(":")
    try:
        focal_mm = float(focal)
    except ValueError:
        raise InputError(f"--lensfun {text!r}: expected CAMERA:FOCAL_MM, e.g. "
                         "'Coolpix P1000:71.9'") from None
    try:
        spec = lensfun_profile(camera, focal_mm, (shape[1], shape[0]), focal_px)
    except InputError as exc:
        raise InputError(f"--lensfun {text!r}: {exc}") from None
    return spec.distortion
