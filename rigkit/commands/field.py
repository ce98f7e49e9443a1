"""``rigkit field``: the guided capture in a terminal (the TUI in :mod:`rigkit.tui`)."""

from __future__ import annotations

import argparse
from pathlib import Path

from rigkit.commands import output_folder

EXAMPLE = """examples:
  rigkit field --demo                       the whole flow on a synthetic scene, no hardware
  rigkit field                              the sessions in ./capture: resume one or start one
  rigkit field capture/ridge-0412 --rig rigs/p1000-tripod.yaml --watch /media/card \\
      --port /dev/rfcomm0

keys: n next step, b back, o add a file, Enter mark a target, m type a range, q quit.
Everything is saved as it happens; run the same command again to resume.
The field guide is docs/field.md.
"""


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "field",
        help="guided capture at the tripod: frames, on-site checks, laser targets, verdict",
        description="The field TUI: walks through the left, right and back positions, "
        "checks every frame on site, records laser targets and processes the session.",
        epilog=EXAMPLE,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("session", type=output_folder, nargs="?", metavar="SESSION",
                   help="session folder to resume, or to create (with --rig)")
    p.add_argument("--rig", type=Path, metavar="PROFILE", help="rig profile for a new session")
    p.add_argument("--watch", type=Path, metavar="DIR",
                   help="folder new frames arrive in (card mount, tethering download folder)")
    p.add_argument("--port", metavar="URL", help="rangefinder pyserial URL, e.g. /dev/rfcomm0 "
                   "or sim://trupulse (default: the rig profile's, else ranges are typed in)")
    p.add_argument("--protocol", default="trupulse", help="rangefinder protocol (trupulse, "
                   "vectronix)")
    p.add_argument("--capture", type=output_folder, default=Path("capture"), metavar="DIR",
                   help="folder of sessions listed at the start (default ./capture)")
    p.add_argument("--demo", action="store_true",
                   help="synthetic scene, simulated camera and rangefinder, in a temporary folder")
    p.set_defaults(runner="rigkit.commands.field_run:run")
