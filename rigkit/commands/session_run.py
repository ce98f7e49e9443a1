"""Running ``rigkit session``'s actions but ``set-position`` and ``set-rig`` (the
arguments: :mod:`rigkit.commands.session`)."""

from __future__ import annotations

import argparse
import json
import sys
from dataclasses import asdict

from rigkit.capture import POSITIONS, frame_problems, load_session, session_to_data, utc_now
from rigkit.capture.actions import changing, create_session, remove_frame, stored_name
from rigkit.capture.checks import check_capture
from rigkit.capture.comparisons import LOG_NAME, Comparison, latest_run, read_rows
from rigkit.capture.field import ingest
from rigkit.capture.lock import lock_holder
from rigkit.capture.model import LaserReading, Session, stray_readings
from rigkit.capture.readings import reading_from_device
from rigkit.capture.results import session_record, stale_results
from rigkit.capture.targets import add_target, remove_reading, remove_target
from rigkit.capture.tripod import check_direction
from rigkit.core.tables import visible, warn
from rigkit.errors import InputError, RigkitError, environment_message
from rigkit.rangefinder import open_rangefinder
from rigkit.rangefinder.protocols import default_protocol
from rigkit.rangefinder.ranging import parse_typed_range
from rigkit.reporting.scale import calibration_targets, scale_source
from rigkit.reporting.verdict import CALIBRATED_LABEL, row_label


def run_new(args: argparse.Namespace) -> int:
    session = create_session(args.session, args.rig, operator=args.operator, notes=args.notes)
    print(f"created session {session.path} (rig {session.rig().name}); next: add the left, "
          "right and back frames with `rigkit session add-frame`")
    return 0


def run_add_frame(args: argparse.Namespace) -> int:
    # A frame of another view or scene is none of the burst (as in the TUI).
    done = ingest(load_session(args.session), args.position, args.file,
                  replace_existing=args.replace, burst=args.burst, check_burst=args.burst)
    if done.held is not None:
        raise InputError(f"{done.held}; add it at the position it shows")
    session = done.session
    burst = session.bursts[args.position]
    frame = burst[-1]
    if stored_name(args.file.name) != args.file.name:
        print(f"note: {visible(args.file.name, lines=False)} holds characters that are not "
              f"shown as they are (control, invisible or not UTF-8): stored as {frame.file}, "
              "the name as given kept as its source in session.yaml")
    width, height = frame.size_px
    count = f", frame {len(burst)} of the burst" if len(burst) > 1 else ""
    print(f"{args.position}: {frame.file} ({width}x{height} px, sha256 {frame.sha256[:12]}"
          f"{count})")
    missing = [p for p in ("left", "right", "back") if p not in session.frames]
    if missing:
        print("still needed: " + ", ".join(missing))
    else:
        _print_exif_findings(session)
    return 0


def _print_exif_findings(session: Session) -> None:
    paths = [session.frame_path(p) for p in ("left", "right", "back")]
    findings = check_capture(session.rig(), paths)
    for finding in findings:
        print(f"warning: {visible(finding.message, lines=False)}")
    if not findings:
        print("all three frames present; EXIF agrees with the rig profile")


def run_add_target(args: argparse.Namespace) -> int:
    session = load_session(args.session)
    name = args.name or _next_name(session)
    stopped = None
    if args.range_m is not None:
        readings = _typed_readings(session, args.range_m, args.inclination, args.azimuth)
    else:
        readings, stopped = _device_readings(session, args)
    session = add_target(session, name, tuple(args.pixel), window_px=args.window,
                         readings=readings, note=args.note)
    target = session.target(name)
    ranges = ", ".join(f"{r.slope_distance_m:.2f}" for r in target.readings)
    print(f"target {name} at ({target.pixel[0]:g}, {target.pixel[1]:g}): "
          f"{len(target.readings)} reading(s) [{ranges}] m")
    if stopped is not None:
        raise InputError(stopped)
    return 0


def _next_name(session: Session) -> str:
    taken = {t.name for t in session.targets}
    n = 1
    while f"T{n}" in taken:
        n += 1
    return f"T{n}"


def _typed_readings(session: Session, ranges: list[str], inclination: float | None,
                    azimuth: float | None = None) -> list[LaserReading]:
    check_direction(azimuth, inclination)
    return [LaserReading(parse_typed_range(r, session.rig()), utc_now(), "manual", inclination,
                         azimuth_deg=azimuth)
            for r in ranges]


def _device_readings(session: Session, args: argparse.Namespace
                     ) -> tuple[list[LaserReading], str | None]:
    """The readings of ``--shots`` shots from the device, and why it stopped early (None
    when it did not): readings received before a lost device are kept, not thrown away."""
    spec = session.rig().rangefinder
    url = args.device
    if url == "rig":
        if spec is None or spec.port is None:
            raise InputError("--device: the rig profile names no rangefinder port; give the "
                             "port, e.g. --device /dev/ttyUSB0")
        url = spec.port
    protocol = args.protocol or (spec.protocol if spec and spec.protocol != "manual"
                                 else default_protocol(url))
    if args.shots < 1:
        raise InputError(f"--shots {args.shots}: expected at least 1")
    readings: list[LaserReading] = []
    baud = spec.baud if spec is not None and url == spec.port else None
    try:
        with open_rangefinder(url, protocol, baud=baud, timeout=args.timeout) as device:
            for shot in range(args.shots):
                print(f"waiting for reading {shot + 1}/{args.shots} from {device.name} ...",
                      flush=True)
                readings.append(reading_from_device(device.read(), f"{protocol}:{url}"))
    except (RigkitError, OSError) as exc:
        if not readings:
            raise
        reason = str(exc) if isinstance(exc, RigkitError) else environment_message(exc)
        return readings, (f"the rangefinder stopped at reading {len(readings) + 1} of "
                          f"{args.shots} ({reason}); the {len(readings)} received are kept")
    return readings, None


def run_remove_reading(args: argparse.Namespace) -> int:
    session = remove_reading(load_session(args.session), args.target, args.reading)
    left = ", ".join(f"{r.slope_distance_m:.2f}" for r in session.target(args.target).readings)
    print(f"removed reading {args.reading} of {args.target}; left: [{left or 'none'}] m")
    return 0


def run_remove_target(args: argparse.Namespace) -> int:
    remove_target(load_session(args.session), args.target)
    print(f"removed target {args.target}")
    return 0


def run_remove_frame(args: argparse.Namespace) -> int:
    session = remove_frame(load_session(args.session), args.position, args.frame)
    left = len(session.bursts.get(args.position, ()))
    print(f"removed a {args.position} frame ({left} left; its file stays in raw/)")
    return 0


def run_show(args: argparse.Namespace) -> int:
    try:  # repair what an interrupted command left, where the session can be changed
        with changing(args.session, "show", wait_s=0.0) as session:
            pass
    except InputError as exc:  # busy, read-only or hostile: say why, show it as it is
        session = load_session(args.session)  # one that cannot be read says only that
        print(f"warning: not repaired: {visible(str(exc), lines=False)}", file=sys.stderr)
    if args.json:
        print(json.dumps(_show_data(session), indent=2))
    else:
        print(visible(_show_text(session)))
    return 0


def _processed(session: Session, stale: str | None) -> str:
    """"processed (run ...)" where the results show the session as it is, else "ready
    to process" (what makes them stale is said below it)."""
    record = session_record(session.path) if stale is None else None
    run = record.run_id if record is not None else None
    if run is None:
        return "ready to process"
    return f"processed (run {run}); rigkit process again to redo it"


def _show_data(session: Session) -> dict[str, object]:
    data = session_to_data(session)
    data["problems"] = frame_problems(session)
    data["last_run"] = [asdict(row) for row in _last_rows(session)]
    data["scale"] = scale_source(session.rig())
    data["calibration_targets"] = sorted(calibration_targets(session.rig(), session))
    return data


def _last_rows(session: Session) -> list[Comparison]:
    log = session.path / LOG_NAME
    torn: list[str] = []
    try:
        rows = latest_run(read_rows(log, torn)) if log.is_file() else []
    except InputError as exc:  # the session is shown all the same
        torn, rows = [str(exc)], []
    warn(torn)
    return rows


def _show_text(session: Session) -> str:
    lines = [f"session {session.name}  ({session.path})", f"  created {session.created_utc}"]
    if session.operator:
        lines.append(f"  operator {session.operator}")
    if session.notes:
        lines.append(f"  notes    {session.notes}")
    rig = session.rig()
    lines.append(f"  rig      {rig.name} (from {session.rig_reference}): f {rig.focal_px:.1f} "
                 f"px, C_lr {rig.baseline_lr.value_m:g} m, C_lb {rig.baseline_lb.value_m:g} m")
    lines.append(f"  scale    {scale_source(rig)}")
    if session.tripod is not None:
        t = session.tripod
        geoid = ("" if t.geoid_separation_m is None
                 else f", geoid {t.geoid_separation_m:.2f} m above the ellipsoid")
        lines.append(f"  tripod   {t.lat_deg:.7f}, {t.lon_deg:.7f}, {t.height_m:.2f} m "
                     f"({t.source}; height {t.height_datum}{geoid})")
    lines.append("frames")
    for position in POSITIONS:
        burst = session.bursts.get(position, ())
        if not burst:
            lines.append(f"  {position:<5}  (missing)")
        for i, frame in enumerate(burst):
            exif = frame.exif
            shot = ", ".join(str(exif[k]) for k in ("model", "datetime_original") if k in exif)
            label = position if i == 0 else ""
            lines.append(f"  {label:<5}  {frame.file}  {frame.size_px[0]}x{frame.size_px[1]}  "
                         f"sha256 {frame.sha256[:12]}  {shot}".rstrip())
    lines.append(f"targets ({len(session.targets)})")
    for target in session.targets:
        strays = stray_readings(target)
        ranges = ", ".join(f"{i + 1}: {r.slope_distance_m:.2f}" + (" (stray)" if i in strays
                                                                    else "")
                           for i, r in enumerate(target.readings)) or "none"
        lines.append(f"  {target.name:<8} pixel ({target.pixel[0]:g}, {target.pixel[1]:g}) "
                     f"window {target.window_px}  laser [{ranges}] m  {target.note}".rstrip())
    problems = frame_problems(session)
    stale = stale_results(session)
    lines.append("status   " + ("; ".join(problems) if problems else _processed(session, stale)))
    for note in filter(None, (lock_holder(session.path), stale)):
        lines.append(f"         {note}")
    rows = _last_rows(session)
    used = calibration_targets(rig, session)
    if rows:
        lines.append(f"last run {rows[0].run_id}")
        for row in rows:
            mark = f" ({CALIBRATED_LABEL})" if row.target in used else ""
            lines.append(f"  {row.target:<8} laser {row.laser_range_m:9.2f} m  estimate "
                         f"{row.estimate_range_m:9.2f} m  error {row.error_pct:+6.2f} %  "
                         f"{row_label(row)}{mark}")
    return "\n".join(lines)
