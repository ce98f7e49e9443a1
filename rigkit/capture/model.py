"""What a capture session is, as values: the names in its folder, and the frames, laser
targets and readings that its ``session.yaml`` records (read, checked and written by
:mod:`rigkit.capture.session`)."""

from __future__ import annotations

import statistics
from collections.abc import Mapping
from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path
from typing import Any

from rigkit.capture.tripod import TripodPosition
from rigkit.errors import InputError
from rigkit.rig.profile import RigProfile, rig_from_data

SESSION_FILE = "session.yaml"
POSITIONS = ("left", "right", "back")
FIELD_STEPS = ("rig", *POSITIONS, "targets", "process")
"""The steps of a capture at the tripod (``rigkit field``), in order."""
FIELD_STEP_KEY = "field_step"
RAW_DIR = "raw"
DERIVED_DIR = "derived"
HISTORY_FILE = "history.log"
STAGING_DIR = ".staging"
LOCK_FILE = ".lock"
EDIT_WAIT_S = 20.0
"""How long a change to a session waits for another one to finish before it gives up."""
DEFAULT_WINDOW_PX = 9
MAX_SIDE_PX = 100_000
"""The largest frame side a session may record, px (a rig profile's limit too)."""


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
    """The step of :data:`FIELD_STEPS` ``rigkit field`` was last on, None if never; as
    written in ``session.yaml``, so possibly a step this rigkit does not know or ``""``."""

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
