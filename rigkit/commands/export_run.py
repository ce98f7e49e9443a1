"""Running ``rigkit export`` (its arguments: :mod:`rigkit.commands.export`)."""

from __future__ import annotations

import argparse

from rigkit.core.progress import Progress
from rigkit.errors import InputError
from rigkit.export import export_path, parse_formats
from rigkit.export.georef import MAX_RESIDUAL_DEG
from rigkit.export.run import Exported


def run(args: argparse.Namespace) -> int:
    formats = parse_formats(args.format)
    residual = MAX_RESIDUAL_DEG if args.max_residual_deg is None else args.max_residual_deg
    if not 0 < residual <= 180:
        raise InputError(f"--max-residual-deg {residual:g}: expected more than 0 degrees")
    task = args.source.name or str(args.source)
    with Progress("export", [task], quiet=args.quiet) as progress:
        done = export_path(args.source, args.out, formats, step=args.step, frame=args.frame,
                           max_residual_deg=residual,
                           progress=lambda stage, f: progress.update(task, f, stage))
    for line in summary(done):
        print(line)
    return 0


def summary(done: Exported) -> list[str]:
    """What an export wrote, where, in which frame; the orientation fit when georeferenced."""
    lines = [f"wrote {', '.join(str(p) for p in done.files)}",
             f"  {done.points} points, median z {done.median_z_m:.2f} m, {done.seconds:.1f} s",
             f"  frame {done.frame}"]
    if done.georef is not None:
        georef, fit = done.georef, done.georef.orientation
        azimuth, elevation, roll = fit.pointing()
        east, north, height = georef.origin
        residuals = ", ".join(f"{name} {r:.2f}" for name, r in
                              zip(fit.names, fit.residuals_deg, strict=True))
        lines += [f"  tripod E {east:.2f} N {north:.2f} height {height:.2f} m "
                  f"({georef.position.source})",
                  f"  camera looks {azimuth:.2f} deg from true north, {elevation:+.2f} deg "
                  f"up, roll {roll:+.2f} deg; {len(fit.names)} targets spanning "
                  f"{fit.spread_deg:.2f} deg, residuals (deg) {residuals}, "
                  f"RMS {fit.rms_residual_deg:.2f}"]
        lines += [f"  left out: {note}" for note in georef.left_out]
    return lines
