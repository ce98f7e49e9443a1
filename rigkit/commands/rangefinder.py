"""``rigkit rangefinder``: read a laser rangefinder, log readings, or simulate one."""

from __future__ import annotations

import argparse
import math

from rigkit.commands import count, output_log
from rigkit.rangefinder.defaults import DEFAULT_BAUDS, DEFAULT_TIMEOUT_S, SIM_OPTIONS

READ_EXAMPLE = """\
examples:
  rigkit rangefinder read --port /dev/ttyUSB0
  rigkit rangefinder read --rig rigs/vehicle-2m.yaml
  rigkit rangefinder read --port /dev/rfcomm0 --json --timeout 60
  rigkit rangefinder read --port /dev/ttyUSB1 --protocol vectronix --baud 115200
  rigkit rangefinder read --port "sim://trupulse?distance=234&noise=0.05"

A TruPulse sends a reading when you fire it; read waits up to --timeout.
"""

LOG_EXAMPLE = """\
examples:
  rigkit rangefinder log --port /dev/rfcomm0 --output field/laser.jsonl
  rigkit rangefinder log --port /dev/ttyUSB1 --protocol vectronix --interval 1 \\
      --output laser.jsonl --raw-log laser-raw.txt

Appends one JSON object per reading to --output (flushed as it arrives) until
Ctrl-C, --count readings, or --timeout seconds without a reading.
"""

SIMULATE_EXAMPLE = """\
examples:
  rigkit rangefinder simulate                  # prints e.g. /dev/pts/5
  rigkit rangefinder read --port /dev/pts/5    # in another shell
  rigkit rangefinder simulate "sim://trupulse?distance=234&unit=F&garbage=0.3"
  rigkit rangefinder simulate "sim://vectronix?noise=0.05"

The same sim:// URL also works directly as --port of read and log.
"""


def _positive(text: str) -> float:
    value = float(text)
    if not (value > 0 and math.isfinite(value)):
        raise argparse.ArgumentTypeError(f"must be a positive number of seconds, got {text}")
    return value


def _add_port_options(parser: argparse.ArgumentParser, *, timeout_help: str) -> None:
    parser.add_argument(
        "--port",
        metavar="URL",
        help="serial device or pyserial URL: /dev/ttyUSB0, /dev/rfcomm0, COM3, "
        "socket://host:port, sim://trupulse (default: the --rig profile's)",
    )
    parser.add_argument(
        "--rig",
        metavar="PROFILE",
        help="rig profile YAML whose rangefinder section gives port, protocol and baud "
        "(flags override it)",
    )
    parser.add_argument(
        "--protocol",
        choices=sorted(DEFAULT_BAUDS),
        help="default: the --rig profile's, else trupulse",
    )
    defaults = ", ".join(f"{name} {baud}" for name, baud in DEFAULT_BAUDS.items())
    parser.add_argument(
        "--baud", type=int, metavar="N", help=f"default: the --rig profile's, else {defaults}"
    )
    parser.add_argument(
        "--bytesize", type=int, choices=(5, 6, 7, 8), default=8, help="data bits (default 8)"
    )
    parser.add_argument(
        "--parity", choices=("N", "E", "O", "M", "S"), default="N", help="(default N)"
    )
    parser.add_argument(
        "--stopbits", type=float, choices=(1, 1.5, 2), default=1, help="(default 1)"
    )
    parser.add_argument("--timeout", type=_positive, metavar="S", help=timeout_help)
    parser.add_argument(
        "--trigger",
        action="store_true",
        help="fire the device from the computer ($GO) instead of waiting for a shot "
        "(TruPulse 360B-class firmware; vectronix is always requested)",
    )
    parser.add_argument("--json", action="store_true", help="print one JSON object per reading")
    parser.add_argument(
        "--raw-log", type=output_log, metavar="FILE",
        help="append all raw serial traffic to FILE (for audit)"
    )


def register(subparsers: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Add ``rangefinder`` with its ``read``, ``log`` and ``simulate`` subcommands."""
    parser = subparsers.add_parser(
        "rangefinder",
        help="read a laser rangefinder (TruPulse, Vectronix) for ground truth",
        description="Read laser-rangefinder ground truth over a serial line, or simulate one.",
        epilog="example: rigkit rangefinder read --port /dev/ttyUSB0 --json",
    )
    sub = parser.add_subparsers(dest="action", metavar="ACTION", required=True)
    formatter = argparse.RawDescriptionHelpFormatter

    read = sub.add_parser(
        "read",
        help="print one reading",
        description="Wait for one reading and print it (slope distance in metres).",
        epilog=READ_EXAMPLE,
        formatter_class=formatter,
    )
    _add_port_options(
        read, timeout_help=f"seconds to wait for the reading (default {DEFAULT_TIMEOUT_S:g})"
    )
    read.set_defaults(runner="rigkit.commands.rangefinder_run:run_read")

    log = sub.add_parser(
        "log",
        help="append readings to a file until stopped",
        description="Keep reading and append each reading to a JSON-lines file.",
        epilog=LOG_EXAMPLE,
        formatter_class=formatter,
    )
    _add_port_options(
        log, timeout_help="stop after S seconds without a reading (default: wait forever)"
    )
    log.add_argument("--output", type=output_log, required=True, metavar="FILE",
                     help="JSON-lines file to append to")
    log.add_argument("--count", type=count, metavar="N", help="stop after N readings")
    log.add_argument(
        "--interval",
        type=_positive,
        default=1.0,
        metavar="S",
        help="seconds between requests when the computer fires the device (default 1)",
    )
    log.set_defaults(runner="rigkit.commands.rangefinder_run:run_log")

    simulate = sub.add_parser(
        "simulate",
        help="run a simulated rangefinder on a pseudo-terminal",
        description="Serve a simulated rangefinder on a pseudo-terminal and print its "
        "device path; runs until Ctrl-C.",
        epilog=SIMULATE_EXAMPLE + "\n" + _simulator_options(),
        formatter_class=formatter,
    )
    simulate.add_argument(
        "url",
        nargs="?",
        default="sim://trupulse",
        metavar="SIM_URL",
        help="sim://trupulse or sim://vectronix with ?key=value options (default sim://trupulse)",
    )
    simulate.set_defaults(runner="rigkit.commands.rangefinder_run:run_simulate")


def _simulator_options() -> str:
    width = max(len(name) for name in SIM_OPTIONS)
    lines = [f"  {name:<{width}}  {text}" for name, text in SIM_OPTIONS.items()]
    return "simulator options:\n" + "\n".join(lines) + "\n"
