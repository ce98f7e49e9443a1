"""Where a rig profile's scale comes from once ``rigkit rig calibrate`` wrote it: the
profile's ``calibration:`` block (docs/rig-profiles.md), read and written here (the rest
of the profile: :mod:`rigkit.rig.profile`). A profile without one is taped.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import Any

from rigkit.core.yamlfile import KeyPath
from rigkit.rig.defaults import MAX_RANGE_M


@dataclass(frozen=True)
class CalibrationSource:
    """One session whose laser targets calibrated a profile: its name and folder (plain
    text), ``frames_sha256`` (one hash of its frames' hashes: the capture itself, wherever
    it is copied), the run its targets came from, when its frames were taken (EXIF, else
    when the session was made), the targets it gave the fit (name -> pixel u, v), those
    held out of it as checks and those left out as blunders."""

    name: str
    path: str
    frames_sha256: str
    run_id: str
    taken: str
    used: Mapping[str, tuple[float, float]] = field(default_factory=dict, hash=False)
    held_out: tuple[str, ...] = ()
    rejected: tuple[str, ...] = ()


@dataclass(frozen=True)
class Calibration:
    """Where a profile's scale comes from once ``rigkit rig calibrate`` wrote it (the
    profile's ``calibration:`` block; a profile without one is taped): when, from which
    profile, the sessions and their targets, the depth it pinned the scale at (m), what
    it changed (one line each), its checks (one line) and the a-posteriori standard
    deviation of unit weight with its degrees of freedom (NaN, 0 where it has none)."""

    date_utc: str
    from_profile: str
    sessions: tuple[CalibrationSource, ...]
    reference_depth_m: float
    changes: tuple[str, ...] = ()
    checks: str = ""
    sigma0: float = float("nan")
    dof: int = 0

    def source(self, frames_sha256: str) -> CalibrationSource | None:
        """The calibrating session with these frames, if one was."""
        return next((s for s in self.sessions if s.frames_sha256 == frames_sha256), None)


def read_calibration(value: Any, key: KeyPath) -> Calibration:
    keys = key.mapping(value, required=("date_utc", "from_profile", "reference_depth_m",
                                        "sessions"),
                       optional=("changes", "checks", "sigma0", "dof"))
    sessions = key.child("sessions")
    listed = sessions.sequence(keys["sessions"])
    if not listed:
        raise sessions.error("must list the sessions the calibration came from")
    changes = key.child("changes")
    return Calibration(
        date_utc=key.child("date_utc").line(keys["date_utc"]),
        from_profile=key.child("from_profile").line(keys["from_profile"]),
        sessions=tuple(_calibration_source(item, sessions.item(i))
                       for i, item in enumerate(listed)),
        reference_depth_m=key.child("reference_depth_m").bounded(
            keys["reference_depth_m"], "m", MAX_RANGE_M),
        changes=tuple(changes.item(i).line(line) for i, line in enumerate(
            changes.sequence(keys.get("changes")))),
        checks=key.child("checks").text(keys["checks"]) if "checks" in keys else "",
        sigma0=(key.child("sigma0").number(keys["sigma0"], "")
                if keys.get("sigma0") is not None else float("nan")),
        dof=(key.child("dof").integer(keys["dof"], "degrees of freedom", 1_000_000)
             if keys.get("dof") else 0),
    )


def _calibration_source(value: Any, key: KeyPath) -> CalibrationSource:
    keys = key.mapping(value, required=("name", "path", "frames_sha256", "run_id", "taken",
                                        "targets"),
                       optional=("held_out", "rejected"))
    targets = key.child("targets")
    if not isinstance(keys["targets"], dict):
        raise targets.error("must map each target's name to its pixel [u, v]", keys["targets"])
    used = {}
    for name, pixel in keys["targets"].items():
        where = targets.child(str(name))
        if not isinstance(pixel, list) or len(pixel) != 2:
            raise where.error("must be the target's pixel [u, v]", pixel)
        used[where.line(str(name))] = (where.number(pixel[0], "px"),
                                       where.number(pixel[1], "px"))
    names = {part: tuple(key.child(part).item(i).line(str(n)) for i, n in enumerate(
        key.child(part).sequence(keys.get(part)))) for part in ("held_out", "rejected")}
    return CalibrationSource(
        name=key.child("name").line(keys["name"]),
        path=key.child("path").line(keys["path"]),
        frames_sha256=key.child("frames_sha256").line(keys["frames_sha256"]),
        run_id=key.child("run_id").line(keys["run_id"]),
        taken=key.child("taken").line(keys["taken"]),
        used=MappingProxyType(used),
        held_out=names["held_out"],
        rejected=names["rejected"],
    )


def calibration_to_dict(record: Calibration) -> dict[str, Any]:
    data: dict[str, Any] = {
        "date_utc": record.date_utc,
        "from_profile": record.from_profile,
        "reference_depth_m": round(record.reference_depth_m, 3),
        "changes": list(record.changes),
        "checks": record.checks,
    }
    if record.dof:
        data["sigma0"] = round(record.sigma0, 4)
        data["dof"] = record.dof
    data["sessions"] = [{
        "name": s.name, "path": s.path, "frames_sha256": s.frames_sha256,
        "run_id": s.run_id, "taken": s.taken,
        "targets": {name: [round(u, 2), round(v, 2)] for name, (u, v) in s.used.items()},
        **({"held_out": list(s.held_out)} if s.held_out else {}),
        **({"rejected": list(s.rejected)} if s.rejected else {}),
    } for s in record.sessions]
    return data
