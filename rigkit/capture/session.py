"""Capture sessions: the frames, laser targets and rig of one field capture, in a folder.

Layout of ``capture/<session>/`` (see ``docs/sessions.md``)::

    session.yaml      what the session is: rig (reference and a copy of its values),
                      frames (which files are which position - one, or a burst of
                      several - with content hash and EXIF),
                      targets (pixel, window, laser readings), notes, timestamps
    raw/              the original files, copied in byte for byte; rigkit never
                      modifies or deletes anything here
    derived/          decoded RAW frames, cached by content hash (safe to delete)
    .staging/         a frame being checked on its way into raw/ (emptied afterwards)
    results/          the newest ``rigkit process`` output, replaced as a whole
    comparisons.csv   rangefinder-vs-estimate rows, appended by every run
    history.log       append-only log of everything rigkit did to the session

This module is the session's data model and its ``session.yaml`` (read, validated
and written atomically, so the file is always either the old or the new version);
:mod:`rigkit.capture.actions` changes sessions.
"""

from __future__ import annotations

import json
import os
import re
import statistics
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from datetime import UTC, datetime
from functools import cached_property
from pathlib import Path
from typing import Any

from rigkit.capture.tripod import (
    TRIPOD_KEY,
    TripodPosition,
    azimuth_from_data,
    tripod_from_data,
    tripod_to_data,
)
from rigkit.core.files import append_whole, replaced_entry, write_text
from rigkit.core.safefs import read_regular, refusal
from rigkit.core.yamlfile import KeyPath, dump_yaml, read_strict_yaml
from rigkit.errors import InputError
from rigkit.rangefinder.framing import MIN_RANGE_M
from rigkit.rangefinder.ranging import max_range_m
from rigkit.rig.profile import RigProfile, rig_from_data

SESSION_FILE = "session.yaml"
FORMAT = "rigkit-session/1"
POSITIONS = ("left", "right", "back")
FIELD_STEPS = ("rig", *POSITIONS, "targets", "process")
"""The steps of a capture at the tripod (``rigkit field``), in order."""
FIELD_STEP_KEY = "field_step"
RAW_DIR = "raw"
DERIVED_DIR = "derived"
RESULTS_DIR = "results"
HISTORY_FILE = "history.log"
STAGING_DIR = ".staging"
LOCK_FILE = ".lock"
EDIT_WAIT_S = 20.0
"""How long a change to a session waits for another one to finish before it gives up."""
DEFAULT_WINDOW_PX = 9
MAX_SIDE_PX = 100_000
"""The largest frame side a session may record, px (a rig profile's limit too)."""
_NAME = re.compile(r"^[A-Za-z0-9][A-Za-z0-9._-]*$")


def utc_now() -> str:
    """The current time as ISO 8601 UTC with a Z, to the second."""
    return datetime.now(UTC).strftime("%Y-%m-%dT%H:%M:%SZ")


@dataclass(frozen=True)
class Frame:
    """One camera position's file.

    ``file``: path relative to the session folder (under ``raw/``). ``sha256``: hex
    digest of its bytes at ingest. ``size_px``: (width, height) of the decoded image.
    ``source``: where it was copied from. ``exif``: the fields rigkit checks (units as
    in :class:`rigkit.imagefile.exif.ExifInfo`; absent fields left out).
    """

    position: str
    file: str
    sha256: str
    size_px: tuple[int, int]
    added_utc: str
    source: str
    exif: Mapping[str, Any] = field(default_factory=dict, hash=False)


@dataclass(frozen=True)
class LaserReading:
    """One rangefinder shot at a target.

    ``slope_distance_m``: range along the laser's line of sight from its aperture, m.
    ``inclination_deg``: above the horizontal, None if not reported. ``source``:
    ``manual`` (typed in), ``simulated`` or ``<protocol>:<port>`` for a device.
    ``raw``: the device's frame as text, if any. ``azimuth_deg``: the laser's bearing,
    degrees clockwise from north in [0, 360) (true or magnetic: the rig profile's
    ``rangefinder.azimuth``), None if not reported.
    """

    slope_distance_m: float
    time_utc: str
    source: str
    inclination_deg: float | None = None
    raw: str | None = None
    azimuth_deg: float | None = None


@dataclass(frozen=True)
class Target:
    """A point the laser was aimed at.

    ``pixel``: (u, v) in the original left image, px, x right and y down, pixel centres
    at integers. ``window_px``: side of the square window (odd) the depth estimate is
    taken over.
    """

    name: str
    pixel: tuple[float, float]
    window_px: int
    readings: tuple[LaserReading, ...] = ()
    note: str = ""


STRAY_M = 1.0
STRAY_FRACTION = 0.005
"""A reading further than max(STRAY_M, STRAY_FRACTION x range) from the median of its
target's readings is flagged as a stray (a typo, a shot that hit something nearer)."""


def stray_readings(target: Target) -> tuple[int, ...]:
    """Indices (0-based) of ``target``'s readings far from the others: over ``STRAY_M``
    or ``STRAY_FRACTION`` of the range from their median. With two readings that far
    apart both are flagged: which one is wrong cannot be told."""
    values = [r.slope_distance_m for r in target.readings]
    if len(values) < 2:
        return ()
    middle = statistics.median(values)
    limit = max(STRAY_M, STRAY_FRACTION * middle)
    if len(values) == 2:
        return (0, 1) if abs(values[0] - values[1]) > 2 * limit else ()
    return tuple(i for i, value in enumerate(values) if abs(value - middle) > limit)


@dataclass(frozen=True)
class Session:
    """A session as read from ``session.yaml``; ``path`` is its folder.

    ``bursts`` holds each position's frames, oldest first (one, or a burst of several
    taken against heat shimmer); :attr:`frames` the first of each, which fixes the
    position's size, EXIF and pixel grid.
    """

    path: Path
    name: str
    created_utc: str
    rig_reference: str
    rig_sha256: str
    rig_values: Mapping[str, Any] = field(hash=False)
    bursts: Mapping[str, tuple[Frame, ...]] = field(hash=False)
    targets: tuple[Target, ...] = ()
    operator: str = ""
    notes: str = ""
    tripod: TripodPosition | None = None
    """Where the tripod stood (``rigkit session set-position``), None if not recorded."""
    field_step: str | None = None
    """The step of :data:`FIELD_STEPS` ``rigkit field`` was last on, None if never."""

    @property
    def frames(self) -> Mapping[str, Frame]:
        """The first frame of each position that has one."""
        return {pos: burst[0] for pos, burst in self.bursts.items() if burst}

    @property
    def burst_length(self) -> int:
        """Frames per position: the shortest burst (1 before any frame is taken)."""
        return min((len(b) for b in self.bursts.values() if b), default=1)

    @property
    def yaml_path(self) -> Path:
        return self.path / SESSION_FILE

    def rig(self) -> RigProfile:
        """The rig profile from the copy of its values kept in the session."""
        return self._rig

    @cached_property
    def _rig(self) -> RigProfile:
        # Validated once per Session: processing asks for it per target.
        return rig_from_data(dict(self.rig_values), self.yaml_path, "rig.values")

    def frame_path(self, position: str) -> Path:
        """Absolute path of a position's file; InputError if the position has none."""
        if position not in self.frames:
            raise InputError(
                f"{self.path}: no {position} frame (add it with "
                f"`rigkit session add-frame {self.path} --position {position} FILE`)"
            )
        return self.path / self.frames[position].file

    def target(self, name: str) -> Target:
        for target in self.targets:
            if target.name == name:
                return target
        raise InputError(f"{self.path}: no target named {name!r}")


# -- reading and writing session.yaml ---------------------------------------------------


def is_session(path: Path) -> bool:
    return (path / SESSION_FILE).is_file()


def check_outside(out: Path, sessions: Iterable[Path], what: str) -> None:
    """InputError naming ``what`` where ``out`` (a file or folder a command is to write)
    lies inside one of ``sessions``, links resolved: what a session holds is written by
    rigkit's session commands alone (a report's comparisons.csv there would replace the
    session's log, a profile its session.yaml)."""
    entry = Path(replaced_entry(out))
    for session in sessions:
        if entry.is_relative_to(os.path.realpath(session)):
            raise InputError(f"{what}: inside the session {session}, whose files are kept as "
                             "captured; write it elsewhere")


def load_session(path: str | Path) -> Session:
    """Read and validate ``session.yaml``; InputError names the file and key. A
    ``session.yaml`` that is a link is refused unread (it could show another file's
    lines in an error), as is a ``name`` that is no plain name."""
    path = Path(path)
    if not path.is_dir():
        raise InputError(f"{path}: no such session folder")
    yaml_path = path / SESSION_FILE
    if yaml_path.is_symlink():
        raise refusal(yaml_path, "a symbolic link")
    if not yaml_path.is_file():
        raise InputError(f"{path}: not a session folder (no {SESSION_FILE})")
    data = read_strict_yaml(yaml_path, "session file")
    return _session_from_data(data, path)


def save_session(session: Session) -> None:
    """Write ``session.yaml`` atomically (temporary file, fsync, rename)."""
    text = "# rigkit capture session; edit with `rigkit session`\n" + dump_yaml(
        session_to_data(session))
    write_text(session.yaml_path, text)


def run_metadata(session_path: Path) -> dict[str, Any] | None:
    """The latest run's ``results/depth.json`` as a mapping; None where the session has
    none that can be read (missing, damaged, or a link or FIFO, which are not opened)."""
    try:
        meta = json.loads(read_regular(session_path / RESULTS_DIR / "depth.json"))
    except (OSError, ValueError, InputError):
        return None
    return meta if isinstance(meta, dict) else None


def log_event(session_path: Path, action: str, detail: str) -> None:
    """Append one line to the session's ``history.log`` (never rewritten; whole or not
    at all, :func:`rigkit.core.files.append_whole`)."""
    append_whole(session_path / HISTORY_FILE, f"{utc_now()}  {action:<12} {detail}\n")


def _session_from_data(data: Any, path: Path) -> Session:
    top_key = KeyPath(path / SESSION_FILE)
    top = top_key.mapping(
        data,
        required=("format", "name", "created_utc", "rig", "frames", "targets"),
        optional=("operator", "notes", TRIPOD_KEY, FIELD_STEP_KEY),
    )
    if top["format"] != FORMAT:
        raise top_key.child("format").error(f"must be {FORMAT}", top["format"])
    rig_key = top_key.child("rig")
    rig = rig_key.mapping(top["rig"], required=("reference", "sha256", "values"))
    if not isinstance(rig["values"], dict):  # its keys are the profile's to check
        raise rig_key.child("values").error("must be a mapping of keys to values", rig["values"])
    frames_key = top_key.child("frames")
    frames_data = frames_key.mapping(top["frames"] or {}, required=(), optional=POSITIONS)
    bursts = {pos: _burst(v, frames_key.child(pos), pos) for pos, v in frames_data.items()}
    targets_key = top_key.child("targets")
    targets = tuple(
        _target(value, targets_key.item(i))
        for i, value in enumerate(targets_key.sequence(top["targets"]))
    )
    names = [t.name for t in targets]
    if len(set(names)) != len(names):
        raise targets_key.error("two targets share a name")
    session = Session(
        path=path,
        name=_plain_name(top["name"], top_key.child("name")),
        created_utc=_text(top["created_utc"], top_key.child("created_utc")),
        rig_reference=_text(rig["reference"], rig_key.child("reference")),
        rig_sha256=_text(rig["sha256"], rig_key.child("sha256")),
        rig_values=rig["values"],
        bursts=bursts,
        targets=targets,
        operator=_text(top.get("operator"), top_key.child("operator")),
        notes=_text(top.get("notes"), top_key.child("notes")),
        tripod=top_key.optional(top, TRIPOD_KEY, tripod_from_data),
        field_step=top_key.optional(top, FIELD_STEP_KEY, _field_step),
    )
    _check_ranges(targets, max_range_m(session.rig()), targets_key)  # validates the rig
    return session


def _field_step(value: Any, key: KeyPath) -> str:
    if value not in FIELD_STEPS:
        raise key.error(f"must be one of {', '.join(FIELD_STEPS)}", value)
    return str(value)


def _check_ranges(targets: tuple[Target, ...], longest_m: float, key: KeyPath) -> None:
    """Every reading a range the rig's rangefinder can give, as typed input must be
    (:data:`MIN_RANGE_M` to ``longest_m``): a 3e-304 m edited into the file would
    otherwise reach every summary."""
    for i, target in enumerate(targets):
        for j, reading in enumerate(target.readings):
            if not MIN_RANGE_M <= reading.slope_distance_m <= longest_m:
                where = key.item(i).child("readings").item(j).child("slope_distance_m")
                raise where.error(f"must be a range the rangefinder gives, {MIN_RANGE_M:g}-"
                                  f"{longest_m:g} m", reading.slope_distance_m)


def _text(value: Any, key: KeyPath) -> str:
    """Text as written; an empty YAML value is empty text."""
    return "" if value is None else key.text(value, strip=False)


def _numbers(value: Any, key: KeyPath, unit: str) -> tuple[float, float]:
    a, b = key.pair(value, "a, b")
    return key.number(a, unit), key.number(b, unit)


def _burst(value: Any, key: KeyPath, position: str) -> tuple[Frame, ...]:
    """A position's frames: one mapping, or a list of them (a burst)."""
    if not isinstance(value, list):
        return (_frame(value, key, position),)
    if not value:
        raise key.error("must list at least one frame", value)
    return tuple(_frame(v, key.item(i), position) for i, v in enumerate(value))


def _frame(value: Any, key: KeyPath, position: str) -> Frame:
    keys = key.mapping(
        value, required=("file", "sha256", "size_px", "added_utc", "source"),
        optional=("exif",),
    )
    size_key = key.child("size_px")
    width, height = (size_key.integer(v, "pixels", MAX_SIDE_PX)
                     for v in size_key.pair(keys["size_px"], "width, height"))
    exif = keys.get("exif") or {}
    if not isinstance(exif, dict):
        raise key.child("exif").error("must be a mapping of keys to values", exif)
    file = _text(keys["file"], key.child("file"))
    if Path(file).is_absolute() or ".." in Path(file).parts:
        raise key.child("file").error("must be a path inside the session", file)
    if any(ord(c) < 32 or ord(c) == 127 for c in file):
        raise key.child("file").error("must be a file name without control characters", file)
    return Frame(
        position=position,
        file=file,
        sha256=_text(keys["sha256"], key.child("sha256")),
        size_px=(width, height),
        added_utc=_text(keys["added_utc"], key.child("added_utc")),
        source=_text(keys["source"], key.child("source")),
        exif=exif,
    )


def _target(value: Any, key: KeyPath) -> Target:
    keys = key.mapping(value, required=("name", "pixel"),
                       optional=("window_px", "readings", "note"))
    name = _text(keys["name"], key.child("name"))
    check_name(name, f"{key.file}: {key.child('name').key}")
    window = keys.get("window_px", DEFAULT_WINDOW_PX)
    if isinstance(window, bool) or not isinstance(window, int) or window < 1 or window % 2 == 0:
        raise key.child("window_px").error("must be an odd positive integer", window)
    readings_key = key.child("readings")
    readings = tuple(
        _reading(item, readings_key.item(i))
        for i, item in enumerate(readings_key.sequence(keys.get("readings")))
    )
    return Target(
        name=name,
        pixel=_numbers(keys["pixel"], key.child("pixel"), "pixels"),
        window_px=window,
        readings=readings,
        note=_text(keys.get("note"), key.child("note")),
    )


def _reading(value: Any, key: KeyPath) -> LaserReading:
    keys = key.mapping(
        value, required=("slope_distance_m", "time_utc", "source"),
        optional=("inclination_deg", "raw", "azimuth_deg"),
    )
    inclination = keys.get("inclination_deg")
    raw = keys.get("raw")
    return LaserReading(
        slope_distance_m=key.child("slope_distance_m").positive(keys["slope_distance_m"], "m"),
        time_utc=_text(keys["time_utc"], key.child("time_utc")),
        source=_text(keys["source"], key.child("source")),
        inclination_deg=None if inclination is None
        else key.child("inclination_deg").number(inclination, "degrees"),
        raw=None if raw is None else key.child("raw").text(raw, strip=False),
        azimuth_deg=key.optional(keys, "azimuth_deg", azimuth_from_data),
    )


def session_to_data(session: Session) -> dict[str, Any]:
    data: dict[str, Any] = {
        "format": FORMAT,
        "name": session.name,
        "created_utc": session.created_utc,
    }
    if session.operator:
        data["operator"] = session.operator
    if session.notes:
        data["notes"] = session.notes
    data["rig"] = {
        "reference": session.rig_reference,
        "sha256": session.rig_sha256,
        "values": dict(session.rig_values),
    }
    data["frames"] = {
        pos: _burst_to_data(session.bursts[pos]) for pos in POSITIONS if session.bursts.get(pos)
    }
    data["targets"] = [_target_to_data(t) for t in session.targets]
    if session.tripod is not None:
        data[TRIPOD_KEY] = tripod_to_data(session.tripod)
    if session.field_step is not None:
        data[FIELD_STEP_KEY] = session.field_step
    return data


def _burst_to_data(burst: tuple[Frame, ...]) -> Any:
    """One frame as a mapping (the layout of sessions before bursts), a burst as a list."""
    return _frame_to_data(burst[0]) if len(burst) == 1 else [_frame_to_data(f) for f in burst]


def _frame_to_data(frame: Frame) -> dict[str, Any]:
    return {
        "file": frame.file,
        "sha256": frame.sha256,
        "size_px": list(frame.size_px),
        "added_utc": frame.added_utc,
        "source": frame.source,
        "exif": dict(frame.exif),
    }


def _target_to_data(target: Target) -> dict[str, Any]:
    data: dict[str, Any] = {
        "name": target.name,
        "pixel": [float(target.pixel[0]), float(target.pixel[1])],
        "window_px": target.window_px,
    }
    if target.note:
        data["note"] = target.note
    data["readings"] = [_reading_to_data(reading) for reading in target.readings]
    return data


def _reading_to_data(reading: LaserReading) -> dict[str, Any]:
    data: dict[str, Any] = {
        "slope_distance_m": reading.slope_distance_m,
        "time_utc": reading.time_utc,
        "source": reading.source,
    }
    if reading.inclination_deg is not None:
        data["inclination_deg"] = reading.inclination_deg
    if reading.azimuth_deg is not None:
        data["azimuth_deg"] = reading.azimuth_deg
    if reading.raw is not None:
        data["raw"] = reading.raw
    return data


def _plain_name(value: Any, key: KeyPath) -> str:
    """A name that may become a file name (``rigkit export`` names its files with the
    session's): the rule of ``session new``, so ``../x`` or ``/x`` is refused on load."""
    name = _text(value, key)
    if not _NAME.match(name):
        raise key.error("not a usable name (letters, digits, '.', '_', '-'; starting with a "
                        "letter or digit)", name)
    return name


def check_name(name: str, where: str) -> None:
    if not _NAME.match(name):
        raise InputError(
            f"{where}: {name!r} is not a usable name (letters, digits, '.', '_', '-'; "
            "starting with a letter or digit)"
        )
