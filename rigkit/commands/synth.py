"""``rigkit synth``: render a synthetic three-view scene with ground truth."""

from __future__ import annotations

import argparse
from pathlib import Path

from rigkit.commands import finite, output_folder

EXAMPLE = """example:
  rigkit synth out/scene-7 --seed 7                      # paper protocol, 4608x3456, 6 deg, 300 m
  rigkit synth out/small --seed 1 --width 1152 --height 864
  rigkit synth out/vehicle --seed 3 --rig rigs/vehicle-2m.yaml   # size, f, baselines from a rig
  rigkit synth capture/synth-5 --seed 5 --width 1152 --height 864 --session --targets 6
  rigkit synth capture/synth-6 --seed 6 --width 1152 --height 864 --session \
      --position 46.55123,7.98456,1012,49.6 --pointing 47.3,-50   # on the map
  rigkit synth out/field-9 --seed 9 --field                 # sky, haze, shimmer, exposure...
  rigkit synth out/field-9b --seed 9 --field --burst 5 --distortion 0.47
  rigkit synth out/town-4 --seed 4 --movers 8 --shadows 2 --facades 2   # what moves, hard walls
  rigkit synth out/air-9 --seed 9 --field --shimmer-spectrum vonkarman --shimmer-outer 1500
  rigkit synth out/valley-2 --seed 2 --backdrop ground --depth-ratio 2 --sky 0.3

flags given explicitly override the rig profile; without --rig the defaults are the paper's.
"""
# rigkit.synth.shimmer.SPECTRA, named here so that --help does not import the renderer
SHIMMER_SPECTRA = ("gaussian", "fine", "vonkarman")
BACKDROPS = ("terrain", "void", "ground")  # rigkit.synth.scene.BACKDROPS, without numpy


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "synth",
        help="render a synthetic left/right/back scene with ground-truth depth",
        description="Render a random long-range scene seen by the three cameras, with "
        "exact ground-truth depth and poses (layout: docs/synthetic-scenes.md).",
        epilog=EXAMPLE,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("out_dir", type=output_folder, help="folder to write (created if missing)")
    p.add_argument("--seed", type=int, default=0, help="random seed: same seed, same scene")
    p.add_argument("--rig", type=Path, help="rig profile YAML: image size, f, baselines, offset")
    p.add_argument("--width", type=int, help="image width, px (default 4608)")
    p.add_argument("--height", type=int, help="image height, px (default 3456)")
    p.add_argument("--fov", type=finite, help="horizontal field of view, degrees (default 6)")
    p.add_argument("--distance", type=finite, default=300.0, help="scene distance, m")
    p.add_argument("--baseline-lr", type=finite, help="left-right baseline C_lr, m (default 2)")
    p.add_argument("--baseline-lb", type=finite, help="left-back distance C_lb, m (default 2)")
    p.add_argument("--back-up", type=finite, help="back camera raised by, m (default 0.3)")
    p.add_argument("--back-side", type=finite, help="back camera offset right, m (default 0)")
    p.add_argument("--max-tilt", type=finite, default=1.0, help="max x/y rotation, degrees")
    p.add_argument("--max-roll", type=finite, default=5.0, help="max z rotation, degrees")
    p.add_argument("--max-pp-offset", type=finite, default=30.0, help="principal point offset, px")
    p.add_argument("--one-camera", action="store_true",
                   help="one camera moved between the positions: the three views share "
                   "one principal point (default: three cameras, one each)")
    p.add_argument("--relief", type=finite, default=0.03, help="terrain depth range / distance")
    p.add_argument("--noise", type=finite, default=1.5, help="read noise sigma, 8-bit DN")
    field = p.add_argument_group(
        "field conditions",
        "what a real capture adds; --field turns on a realistic set (sky 0.25, haze 1500 m, "
        "gain 0.1, offset 6 DN, vignetting 0.25, shimmer 0.3 px over 1 % of the width); "
        "each flag below overrides it",
    )
    field.add_argument("--field", action="store_true", help="a realistic field capture")
    field.add_argument("--sky", type=finite, help="fraction of the height above the skyline")
    field.add_argument("--haze", type=finite, help="haze extinction length, m (0 = clear)")
    field.add_argument("--gain-jitter", type=finite, help="per-camera gain difference (fraction)")
    field.add_argument("--offset-jitter", type=finite, help="per-frame black-level offset, DN")
    field.add_argument("--vignetting", type=finite, help="brightness lost at the corner (fraction)")
    field.add_argument("--shimmer", type=finite, help="heat shimmer, RMS px per axis")
    field.add_argument("--shimmer-corr", type=finite, help="shimmer correlation length, px")
    field.add_argument("--shimmer-spectrum", choices=SHIMMER_SPECTRA,
                       help="shimmer spectrum: gaussian (one correlation length, the "
                       "default), fine (half its variance 8 times finer) or vonkarman (power "
                       "law with an outer scale; docs/synthetic-scenes.md)")
    field.add_argument("--shimmer-outer", type=finite, metavar="PX",
                       help="vonkarman outer scale, px (default 1500)")
    field.add_argument("--distortion", metavar="K1[,K2[,P1,P2[,K3]]]",
                       help="lens distortion (OpenCV model, normalised coordinates), all views")
    field.add_argument("--burst", type=int, help="frames per camera position (default 1)")
    world = p.add_argument_group(
        "a world that moves",
        "what changes between the three captures (minutes apart) and walls stereo finds "
        "hard; all off by default, and ground_truth/moved_left.npy and "
        "shadow_changed_left.npy mark the left pixels where the views disagree",
    )
    world.add_argument("--movers", type=int, metavar="N",
                       help="cars and people, placed anew in each view")
    world.add_argument("--shadows", type=int, metavar="N",
                       help="cloud shadows drifting between captures")
    world.add_argument("--shadow-drift", type=finite, metavar="M",
                       help="cloud shadow drift between two captures, m (default 6)")
    world.add_argument("--facades", type=int, metavar="N",
                       help="building facades: periodic windows and plain walls, alternately")
    world.add_argument("--backdrop", choices=BACKDROPS,
                       help="terrain (default): ground and sky behind the objects; void: "
                       "no ground, an exactly black background; ground: the cameras look "
                       "down on ground receding up the view, objects standing on it")
    world.add_argument("--depth-ratio", type=finite, metavar="R",
                       help="--backdrop ground: the ground's far range over its near one "
                       "in view (default 1.6; 2 is a valley from 200 to 400 m)")
    p.add_argument("--session", action="store_true",
                   help="write a capture session (raw/, session.yaml, rig.yaml) with "
                   "simulated laser targets, ready for `rigkit process`")
    p.add_argument("--targets", type=int, default=5, help="laser targets in a --session")
    p.add_argument("--laser-noise", type=finite, default=0.05,
                   help="simulated laser noise sigma, m (--session)")
    p.add_argument("--position", metavar="LAT,LON,HEIGHT[,GEOID]",
                   help="put the --session on the map: the tripod at LAT, LON (WGS 84 "
                   "degrees) and HEIGHT m above the ellipsoid, or with GEOID, above mean "
                   "sea level as a GPS gives it (the geoid GEOID m above the ellipsoid); "
                   "the laser's azimuth and inclination to each target from the truth")
    p.add_argument("--pointing", metavar="AZIMUTH,ELEVATION[,ROLL]", default="0,0",
                   help="with --position: where the left camera looks, degrees from true "
                   "north, above the horizontal, and its roll (right side down); default 0,0")
    p.add_argument("--quiet", action="store_true", help="no progress output")
    p.set_defaults(runner="rigkit.commands.synth_run:run")
