"""``rigkit field``: the guided capture in a terminal (the TUI in :mod:`rigkit.tui`).

Only this command's run function imports the TUI (and with it Textual), so the rest of
the command line works without it.
"""

from __future__ import annotations

import argparse
import tempfile
from pathlib import Path

from rigkit.errors import InputError

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
    p.add_argument("session", type=Path, nargs="?", metavar="SESSION",
                   help="session folder to resume, or to create (with --rig)")
    p.add_argument("--rig", type=Path, metavar="PROFILE", help="rig profile for a new session")
    p.add_argument("--watch", type=Path, metavar="DIR",
                   help="folder new frames arrive in (card mount, tethering download folder)")
    p.add_argument("--port", metavar="URL", help="rangefinder pyserial URL, e.g. /dev/rfcomm0 "
                   "or sim://trupulse (default: the rig profile's, else ranges are typed in)")
    p.add_argument("--protocol", default="trupulse", help="rangefinder protocol (trupulse, "
                   "vectronix)")
    p.add_argument("--capture", type=Path, default=Path("capture"), metavar="DIR",
                   help="folder of sessions listed at the start (default ./capture)")
    p.add_argument("--demo", action="store_true",
                   help="synthetic scene, simulated camera and rangefinder, in a temporary folder")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    try:
        from rigkit.synth.demo import prepare_demo
        from rigkit.tui.app import run_field
        from rigkit.tui.config import FieldConfig
    except ImportError as exc:
        raise InputError(f"rigkit field needs the TUI packages ({exc.name} is missing): "
                         "pip install rigkit") from None
    if args.watch is not None and not args.watch.is_dir():
        raise InputError(f"--watch {args.watch}: no such folder")
    if args.rig is not None and not args.rig.is_file():
        raise InputError(f"--rig {args.rig}: no such file")
    from rigkit.rangefinder.protocols import get_protocol

    get_protocol(args.protocol)  # an unknown one is refused now, not on the targets step
    if args.demo:
        from rigkit.capture import create_session

        demo = prepare_demo(Path(tempfile.mkdtemp(prefix="rigkit-demo-")))
        create_session(demo.session, demo.rig)
        config = FieldConfig(capture=demo.capture, session=demo.session, rig=demo.rig,
                             port=args.port, demo=demo)
    else:
        _open_or_create(args.session, args.rig)
        capture = args.session.parent if args.session is not None else args.capture
        config = FieldConfig(capture=capture, session=args.session, rig=args.rig,
                             watch=args.watch, port=args.port, protocol=args.protocol)
    code = run_field(config)
    if args.demo:
        print(f"the demo session is kept in {config.session}")
    return code


def _open_or_create(session: Path | None, rig: Path | None) -> None:
    """Check SESSION before the screen opens, so a bad one is one line: an existing
    session must load; a new one needs --rig and is created here."""
    from rigkit.capture import create_session, is_session, load_session

    if session is None:
        return
    if is_session(session):
        load_session(session)
    elif rig is None:
        raise InputError(f"{session}: not a session; give --rig PROFILE to create it")
    else:
        create_session(session, rig)
