"""Running ``rigkit field`` (its arguments: :mod:`rigkit.commands.field`).

Only :func:`run` imports the TUI (and with it Textual), so the rest of the command line
works without it.
"""

from __future__ import annotations

import argparse
import tempfile
from pathlib import Path

from rigkit.errors import InputError


def run(args: argparse.Namespace) -> int:
    try:
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
    if args.demo:  # rendered once the app shows its first screen
        from rigkit.synth.demo import Demo

        demo = Demo(Path(tempfile.mkdtemp(prefix="rigkit-demo-")))
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
