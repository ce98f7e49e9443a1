"""Running ``rigkit rangefinder read``, ``log`` and ``simulate`` (their arguments:
:mod:`rigkit.commands.rangefinder`)."""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
import time
from pathlib import Path
from typing import TextIO

from rigkit.core.outputs import OutputLog
from rigkit.core.safefs import open_regular
from rigkit.errors import InputError
from rigkit.rangefinder import (
    DEFAULT_TIMEOUT_S,
    PROTOCOLS,
    Rangefinder,
    Reading,
    open_rangefinder,
)
from rigkit.rangefinder.driver import ReadTimeout
from rigkit.rangefinder.follow import QUIET_S, quiet_note
from rigkit.rangefinder.protocols import default_protocol
from rigkit.rangefinder.sim import PtySimulator, parse_sim_url


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


def run_read(args: argparse.Namespace) -> int:
    timeout = DEFAULT_TIMEOUT_S if args.timeout is None else args.timeout
    with _open(args, timeout) as rangefinder:
        reading = rangefinder.read(trigger=True if args.trigger else None)
    _emit(reading, args.json, sys.stdout)
    return 0


def _next_reading(rangefinder: Rangefinder, args: argparse.Namespace) -> Reading:
    """The next reading; without --timeout, waiting for ever but saying every
    ``QUIET_S`` what has arrived meanwhile (:func:`rigkit.rangefinder.follow.quiet_note`:
    a wrong --protocol shows as frames that are never readings)."""
    trigger = True if args.trigger else None
    if args.timeout is not None:
        return rangefinder.read(trigger=trigger)
    while True:
        before = rangefinder.stats
        try:
            return rangefinder.read(timeout=QUIET_S, trigger=trigger)
        except ReadTimeout:
            seen = rangefinder.stats.since(before)
            print(quiet_note(seen, rangefinder.protocol.name, QUIET_S), file=sys.stderr,
                  flush=True)


def _check_output(args: argparse.Namespace) -> None:
    """InputError, before the port is opened, where ``--output`` is no JSON-lines log
    (a raw log of an earlier run: appended to, it would be mixed) or is ``--raw-log``
    too. Whether rigkit may append to it at all is :mod:`rigkit.core.outputs`' rule,
    checked before the command starts."""
    path = args.output
    if args.raw_log is not None and os.path.realpath(args.raw_log) == os.path.realpath(path):
        raise InputError(f"--output {path}: also --raw-log; give the two logs two files")
    try:  # never blocks: a FIFO or a device is refused unopened
        with os.fdopen(open_regular(path, os.O_RDONLY), "rb") as handle:
            first = handle.readline(1 << 16)
    except FileNotFoundError:
        return
    except OSError as exc:
        raise InputError(f"cannot append to {path}: {exc.strerror}") from None
    try:
        ok = not first.strip() or isinstance(json.loads(first), dict)
    except ValueError:
        ok = False
    if not ok:
        raise InputError(f"--output {path}: holds something other than readings (its first "
                         "line is no JSON object); give a new file or a log this command "
                         "wrote")


def _append_to(path: Path) -> TextIO:
    """``path`` opened to append lines (:class:`rigkit.core.outputs.OutputLog`); a last
    line cut short (a log whose writer was stopped mid-line) is ended first, so the next
    reading is a line of its own."""
    output = OutputLog(path, "--output", "readings")
    end = os.fstat(output.fileno()).st_size
    if end > 0 and os.pread(output.fileno(), 1, end - 1) != b"\n":
        output.write("\n")
    return output


def run_log(args: argparse.Namespace) -> int:
    timeout = math.inf if args.timeout is None else args.timeout
    count = 0
    _check_output(args)
    with _open(args, timeout) as rangefinder:
        spec = rangefinder.protocol
        requested = args.trigger or spec.request_by_default
        if requested and args.interval < spec.min_request_interval_s:
            raise InputError(
                f"--interval {args.interval:g} is too short for {spec.name}: requests must "
                f"be at least {spec.min_request_interval_s:g} s apart"
            )
        with _append_to(args.output) as output:
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


def run_simulate(args: argparse.Namespace) -> int:
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
