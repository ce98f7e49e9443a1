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

import os
import re
from collections.abc import Iterable
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

from rigkit.capture.model import (
    DEFAULT_WINDOW_PX,
    FIELD_STEP_KEY,
    HISTORY_FILE,
    MAX_SIDE_PX,
    POSITIONS,
    SESSION_FILE,
    Frame,
    LaserReading,
    Session,
    Target,
)
from rigkit.capture.tripod import (
    TRIPOD_KEY,
    azimuth_from_data,
    tripod_from_data,
    tripod_to_data,
)
from rigkit.core.files import append_whole, replaced_entry, write_text
from rigkit.core.safefs import kind_of, refusal
from rigkit.core.yamlfile import KeyPath, dump_yaml, read_strict_yaml
from rigkit.errors import InputError
from rigkit.rangefinder.framing import MIN_RANGE_M
from rigkit.rangefinder.ranging import max_range_m

FORMAT = "rigkit-session/1"
_NAME = re.compile(r"^[A-Za-z0-9][A-Za-z0-9._-]*$")


def utc_now() -> str:
    """The current time as ISO 8601 UTC with a Z, to the second."""
    return datetime.now(UTC).strftime("%Y-%m-%dT%H:%M:%SZ")


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
        there = path.lstat().st_mode if os.path.lexists(path) else None
        raise InputError(f"{path}: no such session folder" if there is None else
                         f"{path}: {kind_of(there)}, not a session folder")
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
        target_from_data(value, targets_key.item(i))
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
    """The field TUI's bookmark as written, kept whatever it is (a step a newer rigkit
    added stays for it): only ``rigkit field`` reads it, and one it does not know (or an
    empty one, ``""``) makes it start where the capture stands and say why
    (:func:`rigkit.capture.field.resume_step`), so the session stays usable."""
    return value if isinstance(value, str) else ""


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


def target_from_data(value: Any, key: KeyPath) -> Target:
    """A target as session.yaml (and a run's record) holds it; InputError naming ``key``."""
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
    data["targets"] = [target_to_data(t) for t in session.targets]
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


def target_to_data(target: Target) -> dict[str, Any]:
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


def is_plain_name(name: str) -> bool:
    """Whether ``name`` is a plain name (:func:`check_name`'s rule)."""
    return _NAME.match(name) is not None


def check_name(name: str, where: str) -> None:
    if not is_plain_name(name):
        raise InputError(
            f"{where}: {name!r} is not a usable name (letters, digits, '.', '_', '-'; "
            "starting with a letter or digit)"
        )
