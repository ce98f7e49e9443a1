"""``rigkit session``: create a capture session and record its frames and laser targets."""

from __future__ import annotations

import argparse
from pathlib import Path

from rigkit.commands import count, finite, output_folder
from rigkit.commands.session_position import register_set_position, register_set_rig

EXAMPLE = """examples:
  rigkit session new capture/ridge-0412 --rig rigs/p1000-tripod.yaml --operator "A. Field"
  rigkit session add-frame capture/ridge-0412 --position left  DSCN0101.NRW
  rigkit session add-frame capture/ridge-0412 --position right DSCN0102.NRW
  rigkit session add-frame capture/ridge-0412 --position back  DSCN0103.NRW
  rigkit session add-target capture/ridge-0412 --name mast --pixel 2210 1408 --range-m 312.4
  rigkit session add-target capture/ridge-0412 --name barn --pixel 900 2100 --device
  rigkit session show capture/ridge-0412
  rigkit session remove-reading capture/ridge-0412 --target mast --reading 2   # a typo

Frames are copied byte for byte into SESSION/raw/ and hashed; rigkit never changes or
deletes anything there. Layout and file formats: docs/sessions.md.
"""


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "session",
        help="create a capture session; add frames and rangefinder targets; show it",
        description="A capture session is a folder holding the rig profile, the left, "
        "right and back frames, and laser-ranged targets (docs/sessions.md).",
        epilog=EXAMPLE,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    actions = p.add_subparsers(dest="action", metavar="ACTION", required=True)

    new = actions.add_parser("new", help="create a session folder")
    new.add_argument("session", type=output_folder,
                     help="folder to create, e.g. capture/ridge-0412")
    new.add_argument("--rig", type=Path, required=True, help="rig profile YAML (copied in)")
    new.add_argument("--operator", default="", help="who captured it")
    new.add_argument("--notes", default="", help="free text: site, weather, anything")
    new.set_defaults(runner="rigkit.commands.session_run:run_new")

    frame = actions.add_parser("add-frame", help="copy a left/right/back frame into raw/")
    frame.add_argument("session", type=Path)
    frame.add_argument("--position", required=True, choices=("left", "right", "back"))
    frame.add_argument("file", type=Path, help="RAW (NEF, DNG, CR2, ...), PNG, TIFF or JPEG")
    mode = frame.add_mutually_exclusive_group()
    mode.add_argument("--replace", action="store_true",
                      help="swap the position's frame(s) for this one (files stay in raw/)")
    mode.add_argument("--burst", action="store_true",
                      help="add to the position's burst: several frames, median-stacked "
                      "against heat shimmer when processed (docs/sessions.md)")
    frame.set_defaults(runner="rigkit.commands.session_run:run_add_frame")

    target = actions.add_parser("add-target", help="a pixel in the left image and its range")
    target.add_argument("session", type=Path)
    target.add_argument("--pixel", nargs=2, type=finite, metavar=("U", "V"), required=True,
                        help="target centre in the left image, px (x right, y down)")
    target.add_argument("--name", help="target name (default T1, T2, ...); an existing "
                        "name adds readings to that target")
    target.add_argument("--window", type=int, default=9,
                        help="side of the square window the estimate is taken over, px "
                        "(odd, default 9)")
    source = target.add_mutually_exclusive_group(required=True)
    source.add_argument("--range-m", nargs="+", metavar="R",
                        help="laser slope distance(s) typed in, metres (up to the rig "
                        "profile's rangefinder.max_range_m)")
    source.add_argument("--device", nargs="?", const="rig", metavar="URL",
                        help="read from a rangefinder: a serial port or pyserial URL "
                        "(default: the rig profile's port)")
    target.add_argument("--protocol", help="device protocol (default: the rig profile's)")
    target.add_argument("--shots", type=int, default=1, help="readings to take from --device")
    target.add_argument("--timeout", type=finite, default=30.0,
                        help="seconds to wait for each device reading")
    target.add_argument("--inclination", type=finite, help="inclination of typed ranges, deg")
    target.add_argument("--azimuth", type=finite, help="azimuth of typed ranges, deg clockwise "
                        "from north (true or magnetic: the rig profile's rangefinder.azimuth)")
    target.add_argument("--note", default="", help="what the target is")
    target.set_defaults(runner="rigkit.commands.session_run:run_add_target")

    remove = actions.add_parser("remove-reading", help="take back one laser reading")
    remove.add_argument("session", type=Path)
    remove.add_argument("--target", required=True, help="the target's name")
    remove.add_argument("--reading", type=count, required=True,
                        help="which reading, 1 for the first (as `session show` lists them)")
    remove.set_defaults(runner="rigkit.commands.session_run:run_remove_reading")

    drop = actions.add_parser("remove-target", help="take back a target with its readings")
    drop.add_argument("session", type=Path)
    drop.add_argument("--target", required=True, help="the target's name")
    drop.set_defaults(runner="rigkit.commands.session_run:run_remove_target")

    unframe = actions.add_parser("remove-frame",
                                 help="take a frame out of the session (its file stays in raw/)")
    unframe.add_argument("session", type=Path)
    unframe.add_argument("--position", required=True, choices=("left", "right", "back"))
    unframe.add_argument("--frame", type=count,
                         help="which frame of the burst, 1 for the first (default: the newest)")
    unframe.set_defaults(runner="rigkit.commands.session_run:run_remove_frame")

    show = actions.add_parser("show", help="print a session: frames, targets, last results")
    show.add_argument("session", type=Path)
    show.add_argument("--json", action="store_true", help="machine-readable output")
    show.set_defaults(runner="rigkit.commands.session_run:run_show")
    register_set_position(actions)
    register_set_rig(actions)
