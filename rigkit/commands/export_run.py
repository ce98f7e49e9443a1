"""Running ``rigkit export`` (its arguments: :mod:`rigkit.commands.export`)."""

from __future__ import annotations

import argparse

from rigkit.core.progress import Progress
from rigkit.export import MapRequest, export_path, parse_formats
from rigkit.export.georef import MAX_RESIDUAL_DEG
from rigkit.export.run import Exported


def run(args: argparse.Namespace) -> int:
    formats = parse_formats(args.format)
    residual = MAX_RESIDUAL_DEG if args.max_residual_deg is None else args.max_residual_deg
    task = args.source.name or str(args.source)
    with Progress("export", [task], quiet=args.quiet) as progress:
        done = export_path(args.source, args.out, formats, step=args.step, frame=args.frame,
                           max_residual_deg=residual,
                           request=MapRequest(args.crs, args.vertical, args.cell),
                           progress=lambda stage, f: progress.update(task, f, stage))
    for line in summary(done):
        print(line)
    return 0


def summary(done: Exported) -> list[str]:
    """What an export wrote, where, in which frame; the orientation fit, heights and
    transformation when georeferenced; why not on the map where ``auto`` fell back."""
    filled = "" if done.filled is None else f" ({done.filled} filled from a neighbour)"
    lines = [f"wrote {', '.join(str(p) for p in done.files)}",
             f"  {done.points} points{filled}, median z {done.median_z_m:.2f} m, "
             f"{done.seconds:.1f} s",
             f"  frame {done.frame}"]
    if done.note is not None:
        lines.append(f"  not on the map: {done.note}")
    if done.georef is not None:
        georef, fit = done.georef, done.georef.orientation
        azimuth, elevation, roll = fit.pointing()
        sigmas = fit.pointing_sigma_deg()
        east, north, height = georef.origin
        residuals = ", ".join(f"{name} {r:.2f}" for name, r in
                              zip(fit.names, fit.residuals_deg, strict=True))
        accuracy = ("accuracy not stated by PROJ" if georef.map.accuracy_m is None
                    else "exact" if georef.map.accuracy_m == 0
                    else f"accuracy {georef.map.accuracy_m:g} m")
        lines += [f"  tripod E {east:.2f} N {north:.2f} height {height:.2f} "
                  f"({georef.position.source})",
                  f"  heights: {georef.map.heights}",
                  f"  PROJ: {georef.map.operation} ({accuracy})",
                  f"  camera looks {azimuth:.2f} +- {sigmas[0]:.2f} deg from true north, "
                  f"{elevation:+.2f} +- {sigmas[1]:.2f} deg up, roll {roll:+.2f} +- "
                  f"{sigmas[2]:.2f} deg; {len(fit.names)} targets spanning "
                  f"{fit.spread_deg:.2f} deg, residuals (deg) {residuals}, "
                  f"RMS {fit.rms_residual_deg:.2f}"]
        lines += [f"  note: {note}" for note in georef.map.notes]
        lines += [f"  left out: {note}" for note in georef.left_out]
    if done.dsm is not None:
        dsm = done.dsm
        lines.append(f"  dsm: {dsm['width']} x {dsm['height']} cells of {dsm['cell']:g} "
                     f"({dsm['cell_chosen']}), {dsm['cells_with_points']} with points")
    return lines
