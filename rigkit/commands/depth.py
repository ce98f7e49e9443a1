"""``rigkit depth``: dense metric depth of the left view from three images."""

from __future__ import annotations

import argparse
import os
from pathlib import Path

from rigkit.commands import finite, output_file

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
    p.add_argument("--focal-px", type=finite, help="focal length, px (overrides --rig)")
    p.add_argument("--baseline-lr", type=finite, help="left-right baseline C_lr, m")
    p.add_argument("--baseline-lb", type=finite, help="left-back distance C_lb along z, m")
    p.add_argument("--distortion", metavar="K1[,K2[,P1,P2[,K3]]]",
                   help="lens distortion, OpenCV model on normalised coordinates about the "
                   "image centre (overrides --rig's camera.distortion)")
    p.add_argument("--lensfun", metavar="CAMERA:FOCAL_MM",
                   help="lens distortion from lensfun's profile of CAMERA's built-in lens at "
                   "the real focal length FOCAL_MM, e.g. 'Coolpix P1000:71.9'")
    p.add_argument("--one-camera", action="store_true",
                   help="one camera moved between the three positions (as --rig's "
                   "one_camera: true): the views share one principal point, fitted once")
    p.add_argument("--fixed-lens", action="store_true",
                   help="use the given distortion as it is (default: refine it, or fit it "
                   "when none is given, from the three views)")
    p.add_argument("--force", action="store_true",
                   help="compute depth even where the frames' EXIF focal length contradicts "
                   "the rig profile")
    p.add_argument("--out", type=output_file, required=True, help="depth map to write (.npy)")
    p.add_argument("--preview", action="store_true", help="also write colour-mapped PNGs")
    p.add_argument("--quiet", action="store_true", help="no progress output")
    p.set_defaults(runner="rigkit.commands.depth_run:run")


def _frames(text: str) -> list[Path]:
    """One file, or the frames of a burst separated by commas; a file whose own name
    holds a comma is that one file (``a,b.png``: before, two missing files ``a`` and
    ``b.png``)."""
    if "," not in text or os.path.lexists(text):
        return [Path(text)]
    return [Path(p) for p in text.split(",") if p]
