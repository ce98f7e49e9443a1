"""Running ``rigkit synth`` (its arguments: :mod:`rigkit.commands.synth`)."""

from __future__ import annotations

import argparse
import math
import time
from dataclasses import replace
from pathlib import Path
from typing import Any

from rigkit.capture.tripod import GEOID_RANGE_M, check_direction, check_position
from rigkit.commands import parse_distortion
from rigkit.core.progress import Progress
from rigkit.errors import InputError
from rigkit.rig import load_rig
from rigkit.synth import SynthParams, field_params, generate_scene, write_scene
from rigkit.synth.io import VIEWS
from rigkit.synth.placement import Placement
from rigkit.synth.scene import Scene


def _rig_settings(path: Path) -> dict[str, float]:
    rig = load_rig(path)
    w, h = rig.image_size
    side, up = rig.back_offset_m or (0.0, 0.0)
    return {
        "width": w,
        "height": h,
        "fov": math.degrees(2 * math.atan(w / 2 / rig.focal_px)),
        "baseline_lr": rig.baseline_lr.value_m,
        "baseline_lb": rig.baseline_lb.value_m,
        "back_up": up,
        "back_side": side,
    }


def run(args: argparse.Namespace) -> int:
    d = SynthParams()
    settings: dict[str, float] = {
        "width": d.width,
        "height": d.height,
        "fov": d.hfov_deg,
        "baseline_lr": d.baseline_lr_m,
        "baseline_lb": d.baseline_lb_m,
        "back_up": d.back_up_m,
        "back_side": d.back_side_m,
    }
    if args.rig is not None:
        settings.update(_rig_settings(args.rig))
    settings.update({k: getattr(args, k) for k in settings if getattr(args, k) is not None})
    params = SynthParams(
        width=int(settings["width"]),
        height=int(settings["height"]),
        hfov_deg=settings["fov"],
        distance_m=args.distance,
        baseline_lr_m=settings["baseline_lr"],
        baseline_lb_m=settings["baseline_lb"],
        back_up_m=settings["back_up"],
        back_side_m=settings["back_side"],
        max_tilt_deg=args.max_tilt,
        max_roll_deg=args.max_roll,
        max_pp_offset_px=args.max_pp_offset,
        one_camera=args.one_camera,
        relief=args.relief,
        noise_dn=args.noise,
    )
    params = _field_conditions(args, params)
    scene = generate_scene(params, args.seed)
    t0 = time.perf_counter()
    with Progress("synth", VIEWS, quiet=args.quiet) as progress:
        what = _write(args, scene, progress)
    print(
        f"wrote {what} {args.out_dir} ({params.width}x{params.height}, "
        f"f={params.focal_px:.1f} px, seed {args.seed}) in {time.perf_counter() - t0:.1f} s"
    )
    return 0


# Flags of the "field conditions" and "a world that moves" groups -> SynthParams fields.
_CONDITION_FLAGS = {
    "sky": "sky",
    "haze": "haze_m",
    "gain_jitter": "gain_jitter",
    "offset_jitter": "offset_jitter_dn",
    "vignetting": "vignetting",
    "shimmer": "shimmer_px",
    "shimmer_corr": "shimmer_corr_px",
    "shimmer_spectrum": "shimmer_spectrum",
    "shimmer_outer": "shimmer_outer_px",
    "burst": "burst",
    "movers": "n_movers",
    "shadows": "n_shadows",
    "shadow_drift": "shadow_drift_m",
    "facades": "n_facades",
    "backdrop": "backdrop",
    "depth_ratio": "depth_ratio",
}


def _field_conditions(args: argparse.Namespace, params: SynthParams) -> SynthParams:
    """``params`` with --field's preset and the field and world flags given applied."""
    if args.field:
        params = field_params(params)
    changes: dict[str, Any] = {  # flags of several types, checked by SynthParams
        name: getattr(args, flag) for flag, name in _CONDITION_FLAGS.items()
        if getattr(args, flag) is not None
    }
    if args.distortion is not None:
        changes["distortion"] = parse_distortion(args.distortion)
    return replace(params, **changes)


def _placement(args: argparse.Namespace) -> Placement | None:
    """--position and --pointing as a placement on the map (None without --position);
    InputError naming the option whose numbers are not."""
    if args.position is None:
        return None
    position = _numbers(args.position, "--position", (3, 4))
    pointing = _numbers(args.pointing, "--pointing", (2, 3))
    check_position(*position[:3])
    if len(position) == 4 and not GEOID_RANGE_M[0] <= position[3] <= GEOID_RANGE_M[1]:
        raise InputError(f"--position geoid {position[3]:g}: expected {GEOID_RANGE_M[0]:g} "
                         f"to {GEOID_RANGE_M[1]:g} m")
    check_direction(pointing[0] % 360.0, pointing[1])
    return Placement(position[0], position[1], position[2], azimuth_deg=pointing[0] % 360.0,
                     elevation_deg=pointing[1], roll_deg=pointing[2] if len(pointing) == 3 else 0.0,
                     geoid_separation_m=position[3] if len(position) == 4 else None)


def _numbers(text: str, option: str, counts: tuple[int, ...]) -> list[float]:
    try:
        values = [float(part) for part in text.split(",")]
    except ValueError:
        values = []
    if len(values) not in counts or not all(math.isfinite(v) for v in values):
        raise InputError(f"{option} {text!r}: expected {' or '.join(map(str, counts))} "
                         "comma-separated numbers")
    return values


MAX_TARGETS = 1000
"""The most laser targets a synthetic session gets (each is a line of session.yaml)."""


def _write(args: argparse.Namespace, scene: Scene, progress: Progress) -> str:
    """Render ``scene`` as a scene folder or a session; what was written, in words."""
    if args.session:
        from rigkit.synth.session import write_synthetic_session

        if not 0 <= args.targets <= MAX_TARGETS or args.laser_noise < 0:
            raise InputError(f"--targets must be 0 to {MAX_TARGETS} and --laser-noise must "
                             "not be negative")
        session = write_synthetic_session(
            scene, args.out_dir, n_targets=args.targets, laser_sigma_m=args.laser_noise,
            seed=args.seed, progress=progress, placement=_placement(args),
        )
        what = f"session with {len(session.targets)} targets"
        if session.tripod is not None:
            what += f", on the map at {session.tripod.lat_deg:g}, {session.tripod.lon_deg:g}"
    else:
        if args.position is not None:
            raise InputError("--position places a --session on the map: add --session")
        write_scene(scene, args.out_dir, progress)
        what = "scene"
    return what
