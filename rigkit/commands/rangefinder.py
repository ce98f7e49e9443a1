"""``rigkit rangefinder``: read a laser rangefinder, log readings, or simulate one."""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
import time
from typing import TextIO

from rigkit.commands import count
from rigkit.errors import InputError
from rigkit.rangefinder import (
    DEFAULT_TIMEOUT_S,
    PROTOCOLS,
    Rangefinder,
    Reading,
    open_rangefinder,
)
from rigkit.rangefinder.driver import ReadTimeout
from rigkit.rangefinder.protocols import default_protocol
from rigkit.rangefinder.sim import SIM_OPTIONS, PtySimulator, parse_sim_url

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
        choices=sorted(PROTOCOLS),
        help="default: the --rig profile's, else trupulse",
    )
    defaults = ", ".join(f"{spec.name} {spec.default_baud}" for spec in PROTOCOLS.values())
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
        "--raw-log", metavar="FILE", help="append all raw serial traffic to FILE (for audit)"
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
    read.set_defaults(func=_read)

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
    log.add_argument("--output", required=True, metavar="FILE", help="JSON-lines file to append to")
    log.add_argument("--count", type=count, metavar="N", help="stop after N readings")
    log.add_argument(
        "--interval",
        type=_positive,
        default=1.0,
        metavar="S",
        help="seconds between requests when the computer fires the device (default 1)",
    )
    log.set_defaults(func=_log)

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
    simulate.set_defaults(func=_simulate)


def _simulator_options() -> str:
    width = max(len(name) for name in SIM_OPTIONS)
    lines = [f"  {name:<{width}}  {text}" for name, text in SIM_OPTIONS.items()]
    return "simulator options:\n" + "\n".join(lines) + "\n"


def _connection(args: argparse.Namespace) -> tuple[str, str, int | None]:
    """Port, protocol and baud from the flags, falling back to the --rig profile."""
    port, protocol, baud = args.port, args.protocol, args.baud
    if args.rig is not None:
        from rigkit.rig import load_rig

        spec = load_rig(args.rig).rangefinder
        if spec is None:
            raise InputError(f"{args.rig}: the rig profile has no rangefinder section")
        if protocol is None:
            if spec.protocol not in PROTOCOLS:
                raise InputError(
                    f"{args.rig}: rangefinder.protocol {spec.protocol!r} is not read over "
                    f"serial (rigkit reads {', '.join(sorted(PROTOCOLS))}); pass --protocol"
                )
            protocol = spec.protocol
        port = spec.port if port is None else port
        baud = spec.baud if baud is None else baud
    if port is None:
        raise InputError("no port: pass --port URL (or --rig with a rangefinder.port)")
    return port, protocol or default_protocol(port), baud


def _open(args: argparse.Namespace, timeout: float) -> Rangefinder:
    port, protocol, baud = _connection(args)
    return open_rangefinder(
        port,
        protocol,
        baud=baud,
        timeout=timeout,
        log_path=args.raw_log,
        bytesize=args.bytesize,
        parity=args.parity,
        stopbits=args.stopbits,
    )


def _format(reading: Reading) -> str:
    parts = [f"slope {reading.slope_distance_m:.2f} m"]
    if reading.horizontal_distance_m is not None:
        parts.append(f"horizontal {reading.horizontal_distance_m:.2f} m")
    if reading.inclination_deg is not None:
        parts.append(f"inclination {reading.inclination_deg:+.2f} deg")
    if reading.azimuth_deg is not None:
        parts.append(f"azimuth {reading.azimuth_deg:.2f} deg")
    if len(reading.targets_m) > 1:
        others = ", ".join(f"{t:.2f}" for t in reading.targets_m[1:])
        parts.append(f"other targets {others} m")
    notes = [f"sent in {reading.unit}"]
    if reading.low_quality:
        notes.append("low-quality target")
    return ", ".join(parts) + f" ({'; '.join(notes)})"


def _emit(reading: Reading, as_json: bool, out: TextIO) -> None:
    line = json.dumps(reading.to_json_dict()) if as_json else _format(reading)
    print(line, file=out, flush=True)


def _read(args: argparse.Namespace) -> int:
    timeout = DEFAULT_TIMEOUT_S if args.timeout is None else args.timeout
    with _open(args, timeout) as rangefinder:
        reading = rangefinder.read(trigger=True if args.trigger else None)
    _emit(reading, args.json, sys.stdout)
    return 0


QUIET_NOTE_S = 10.0
"""Without --timeout, ``log`` says every this many seconds that nothing has come."""


def _next_reading(rangefinder: Rangefinder, args: argparse.Namespace) -> Reading:
    """The next reading; without --timeout, waiting for ever but saying every
    QUIET_NOTE_S what has arrived meanwhile (a wrong --protocol shows as frames that
    are never readings)."""
    trigger = True if args.trigger else None
    if args.timeout is not None:
        return rangefinder.read(trigger=trigger)
    while True:
        before = rangefinder.stats
        try:
            return rangefinder.read(timeout=QUIET_NOTE_S, trigger=trigger)
        except ReadTimeout:
            seen = rangefinder.stats.since(before)
            hint = (f": not {rangefinder.protocol.name}? (--protocol)" if seen.frames
                    else " (fire the laser, or check the cable and --baud)")
            print(f"no reading in {QUIET_NOTE_S:g} s ({seen.describe()}){hint}",
                  file=sys.stderr, flush=True)


def _log(args: argparse.Namespace) -> int:
    timeout = math.inf if args.timeout is None else args.timeout
    count = 0
    with _open(args, timeout) as rangefinder:
        spec = rangefinder.protocol
        requested = args.trigger or spec.request_by_default
        if requested and args.interval < spec.min_request_interval_s:
            raise InputError(
                f"--interval {args.interval:g} is too short for {spec.name}: requests must "
                f"be at least {spec.min_request_interval_s:g} s apart"
            )
        try:
            output = open(args.output, "a", encoding="utf-8")
        except OSError as exc:
            raise InputError(f"cannot append to {args.output}: {exc.strerror}") from None
        with output:
            try:
                while args.count is None or count < args.count:
                    started = time.monotonic()
                    reading = _next_reading(rangefinder, args)
                    output.write(json.dumps(reading.to_json_dict()) + "\n")
                    output.flush()
                    os.fsync(output.fileno())
                    count += 1
                    _emit(reading, args.json, sys.stdout)
                    if requested and (args.count is None or count < args.count):
                        time.sleep(max(0.0, args.interval - (time.monotonic() - started)))
            except KeyboardInterrupt:
                pass
        noun = "reading" if count == 1 else "readings"
        print(
            f"logged {count} {noun} to {args.output} (line: {rangefinder.stats.describe()})",
            file=sys.stderr,
        )
    return 0


def _simulate(args: argparse.Namespace) -> int:
    config = parse_sim_url(args.url)
    with PtySimulator(config) as simulator:
        print(simulator.path, flush=True)
        print(
            f"simulating {args.url} on {simulator.path}; try: rigkit rangefinder read "
            f"--port {simulator.path} --protocol {config.device}  (Ctrl-C to stop)",
            file=sys.stderr,
            flush=True,
        )
        try:
            while simulator.running:
                simulator.wait(0.5)
        except KeyboardInterrupt:
            return 0
    print("simulated device disconnected", file=sys.stderr)
    return 0
