"""A depth run's files and its record: where they are, what made the run, what it found,
and whether a session's results still show the session.

A run leaves a depth map with its sigma, grey and flags, and a record (``depth.json``):
in a session's ``results/`` (:meth:`RunFiles.of_session`), or beside ``rigkit depth
--out D.npy`` (:meth:`RunFiles.beside`). The record is a frozen, typed
:class:`RunRecord`, written by one writer (:meth:`RunRecord.to_json`) and read by one
reader (:func:`read_record`), which takes nothing on trust: a value rigkit would not
have written (not finite, out of range, of the wrong kind; a 1e200 offset fraction) is
refused with one line naming the file, the key and the value.

What made the run is one value, :class:`RunInputs` (the frames' hashes, the rig
geometry, the pipeline settings and the laser targets, each a whole value), and
:func:`stale_results` compares the recorded one with the session's now, field by field
of the dataclass: a field added to it later is compared without anyone remembering to.
"""

from __future__ import annotations

import json
import os
from collections.abc import Mapping
from dataclasses import dataclass, field, fields, is_dataclass
from pathlib import Path
from typing import Any

from rigkit.capture.comparisons import LOG_NAME, read_rows
from rigkit.capture.model import MAX_SIDE_PX, POSITIONS, Session, Target
from rigkit.capture.session import target_from_data, target_to_data
from rigkit.core.safefs import open_regular
from rigkit.core.yamlfile import KeyPath
from rigkit.errors import InputError
from rigkit.geometry import Distortion, distortion_coefficients
from rigkit.pipeline.lens import Lens
from rigkit.pipeline.rig import RigGeometry
from rigkit.pipeline.settings import PipelineSettings
from rigkit.rig.defaults import MAX_RANGE_M

RESULTS_DIR = "results"
"""A session's newest run, replaced as a whole (:func:`rigkit.core.files.replace_folder`)."""
MAX_RECORD_BYTES = 16 << 20
"""The largest record read: a run's is ~10 kB (100 targets with 10 readings each add
~100 kB)."""
MAX_FOCAL_PX = 1e7
"""The largest focal length a record may hold, px (a rig profile's limit)."""
MAX_BURST = 10_000
"""The most frames per position a record may say were stacked."""


@dataclass(frozen=True)
class RunFiles:
    """Where one run's files are. ``depth``: (H, W) float32 .npy, z along the left
    camera's axis, m, NaN = no estimate; ``sigma``: the same, its one standard error, m;
    ``grey``: (H, W) 8-bit PNG, the left image as the pipeline saw it; ``flags``: (H, W)
    uint8 .npy (:meth:`rigkit.pipeline.DepthResult.flags`); ``record``: the
    :class:`RunRecord` as JSON."""

    depth: Path
    sigma: Path
    grey: Path
    flags: Path
    record: Path

    @classmethod
    def of_session(cls, session_path: Path) -> RunFiles:
        """A session's ``results/``: ``depth.npy``, ``sigma.npy``, ``grey.png``,
        ``flags.npy``, ``depth.json``."""
        folder = Path(session_path) / RESULTS_DIR
        return cls(folder / "depth.npy", folder / "sigma.npy", folder / "grey.png",
                   folder / "flags.npy", folder / "depth.json")

    @classmethod
    def beside(cls, out: Path) -> RunFiles:
        """``rigkit depth --out D.npy``'s: ``D.npy``, ``D.sigma.npy``, ``D.grey.png``,
        ``D.flags.npy``, ``D.json``."""
        out = Path(out)
        stem = out.parent / out.stem
        return cls(out, Path(f"{stem}.sigma.npy"), Path(f"{stem}.grey.png"),
                   Path(f"{stem}.flags.npy"), Path(f"{stem}.json"))


def session_comparisons(session_path: Path) -> Path:
    """The comparison rows of a session's newest run (``results/comparisons.csv``)."""
    return Path(session_path) / RESULTS_DIR / LOG_NAME


Hashes = tuple[str | None, ...]


@dataclass(frozen=True)
class RunInputs:
    """What made a run's depth and comparisons, each field a whole value.
    ``frames``: each position's frames' SHA-256 (hex; None where not hashed, as
    ``rigkit depth`` leaves a frame given once), left, right, back, oldest first;
    ``rig``: the rig as the pipeline took it (focal length, baselines, lens, principal
    points, one camera or three); ``settings``: the pipeline's; ``targets``: the laser
    targets with their readings as the comparisons took them (none for ``rigkit depth``).
    Two runs of the same inputs give the same depth bit for bit."""

    frames: tuple[Hashes, Hashes, Hashes]
    rig: RigGeometry
    settings: PipelineSettings
    targets: tuple[Target, ...] = ()


_WHAT = {"frames": "the frames", "rig": "the rig", "settings": "the pipeline settings",
         "targets": "the targets"}
"""How a message names a field of :class:`RunInputs` (a field added later is named by
its own name until it has words here)."""


def session_inputs(session: Session) -> RunInputs:
    """What a run of ``session`` as it is now would be made from."""
    profile = session.rig()
    return RunInputs(frames=frame_hashes({p: [f.sha256 for f in b]
                                          for p, b in session.bursts.items()}),
                     rig=profile.geometry(), settings=profile.pipeline_settings(),
                     targets=session.targets)


def frame_hashes(bursts: Mapping[str, Any]) -> tuple[Hashes, Hashes, Hashes]:
    """Position -> its frames' hashes, as :attr:`RunInputs.frames`."""
    left, right, back = (tuple(bursts.get(pos, ())) for pos in POSITIONS)
    return left, right, back


def changed_inputs(recorded: RunInputs, current: RunInputs, with_targets: bool = True
                   ) -> str | None:
    """What differs between two :class:`RunInputs`, in words, or None: every field
    compared as a whole value, and of a field that is a dataclass (the rig, the
    settings), which of its own fields differ ("the rig changed (distortion,
    principal_points_px)")."""
    names, parts = [], []
    for item in fields(RunInputs):
        if item.name == "targets" and not with_targets:
            continue
        old, new = getattr(recorded, item.name), getattr(current, item.name)
        if old == new:
            continue
        names.append(_WHAT.get(item.name, item.name))
        if is_dataclass(old) and is_dataclass(new):
            parts += [f.name for f in fields(old) if getattr(old, f.name) != getattr(new, f.name)]
    if not names:
        return None
    return f"{' and '.join(names)} changed" + (f" ({', '.join(parts)})" if parts else "")


@dataclass(frozen=True)
class RecordedFrame:
    """A frame a run read: ``file`` as messages show it (a session's ``raw/...``, or the
    path given to ``rigkit depth``), ``sha256`` its hash (None where not hashed)."""

    file: str
    sha256: str | None = None


@dataclass(frozen=True)
class RunRecord:
    """What a run was made from and what it found, as ``depth.json`` holds it.

    ``frames``: position -> the frames read, oldest first; ``rig``, ``settings`` and
    ``targets`` as in :class:`RunInputs` (:attr:`inputs` gathers what made the run).
    ``run_id``, ``time_utc`` (ISO 8601 UTC), ``rigkit_version``: a processing
    run's (None for ``rigkit depth``'s files). ``rig_name``: the rig profile's name.
    ``image_size_px``: (W, H). ``left_camera_px``: (f, cx, cy) px, the left view's
    focal length and principal point, the centre of its lens's distortion, as the run
    took them (fitted from the views where the run fitted the lens, else the rig
    profile's), pixel centres at integers. ``lens``: OpenCV's (k1, k2, p1, p2, k3) the
    run took out of the views (the rig's, or the one it fitted); with
    ``left_camera_px`` the lens the depth map is back-projected through
    (:attr:`left_lens`). ``burst_length``: frames per position stacked (the shortest
    burst). ``median_depth_m``: the depth map's median z, m (None: no depth).
    ``offset_px``, ``offset_sigma_px``: the disparity offset and its one-sigma error,
    px at full resolution; ``offset_depth_fraction``: that error's share of depth at
    the median depth (one sigma; None where unknown). ``shortfalls``: what the run says
    makes the capture miss the goal; ``warnings``: every warning, shortfalls included.
    ``details``: the rest of the record (the heat shimmer measured, the pipeline's
    diagnostics), for people; rigkit reads none of it back."""

    frames: Mapping[str, tuple[RecordedFrame, ...]]
    rig: RigGeometry
    settings: PipelineSettings
    rig_name: str
    image_size_px: tuple[int, int]
    left_camera_px: tuple[float, float, float]
    lens: Distortion
    burst_length: int
    median_depth_m: float | None
    offset_px: float
    offset_sigma_px: float
    offset_depth_fraction: float | None
    targets: tuple[Target, ...] = ()
    shortfalls: tuple[str, ...] = ()
    warnings: tuple[str, ...] = ()
    run_id: str | None = None
    time_utc: str | None = None
    rigkit_version: str | None = None
    details: Mapping[str, Any] = field(default_factory=dict, hash=False)

    def __post_init__(self) -> None:  # what the typed fields hold is theirs alone
        object.__setattr__(self, "details", {key: value for key, value in self.details.items()
                                             if key not in _TYPED})

    @property
    def left_lens(self) -> Lens:
        """The left view's lens as the run took it out (:attr:`lens` about the principal
        point of :attr:`left_camera_px`), through which every pixel of the depth map is
        back-projected: ``rigkit export``'s points and the laser comparison alike."""
        f, cx, cy = self.left_camera_px
        width, height = self.image_size_px
        return Lens(f, (width, height), self.lens, (cx - (width - 1) / 2, cy - (height - 1) / 2))

    @property
    def inputs(self) -> RunInputs:
        """What made the run, compared whole by :func:`stale_results`."""
        return RunInputs(
            frames=frame_hashes({pos: [f.sha256 for f in burst]
                                 for pos, burst in self.frames.items()}),
            rig=self.rig, settings=self.settings, targets=self.targets)

    def to_json(self) -> str:
        """The record as ``depth.json``: the one writer (:func:`read_record` reads it)."""
        f, cx, cy = self.left_camera_px
        data: dict[str, Any] = {
            "run_id": self.run_id, "rigkit_version": self.rigkit_version,
            "time_utc": self.time_utc,
        }
        data = {key: value for key, value in data.items() if value is not None}
        data.update({
            "frames": {pos: [_frame_data(f) for f in self.frames.get(pos, ())]
                       for pos in POSITIONS},
            "burst_length": self.burst_length,
            "image_size_px": list(self.image_size_px),
            "rig": {"name": self.rig_name, **_plain(_values(self.rig))},
            "settings": _values(self.settings),
            "targets": [target_to_data(t) for t in self.targets],
            "left_camera_px": {"f": f, "cx": cx, "cy": cy},
            "distortion_k1_k2_p1_p2_k3": list(self.lens),
            "median_depth_m": self.median_depth_m,
            "disparity_offset_px": self.offset_px,
            "disparity_offset_sigma_px": self.offset_sigma_px,
            "offset_depth_error_fraction": self.offset_depth_fraction,
            "warnings": list(self.warnings),
            "shortfalls": list(self.shortfalls),
        })
        return json.dumps({**data, **self.details}, indent=2, allow_nan=False)


def _frame_data(frame: RecordedFrame) -> dict[str, str]:
    return {"file": frame.file, **({"sha256": frame.sha256} if frame.sha256 else {})}


def _values(value: Any) -> dict[str, Any]:
    """A dataclass's fields by name (every one: a field added later is recorded)."""
    return {f.name: getattr(value, f.name) for f in fields(value)}


def _plain(data: dict[str, Any]) -> dict[str, Any]:
    """Tuples as lists, as JSON holds them."""
    def plain(value: Any) -> Any:
        return [plain(v) for v in value] if isinstance(value, tuple | list) else value

    return {key: plain(value) for key, value in data.items()}


_TYPED = ("run_id", "rigkit_version", "time_utc", "frames", "burst_length", "image_size_px",
          "rig", "settings", "targets", "left_camera_px", "distortion_k1_k2_p1_p2_k3",
          "median_depth_m", "disparity_offset_px", "disparity_offset_sigma_px",
          "offset_depth_error_fraction", "warnings", "shortfalls")
"""The keys :func:`read_record` reads and checks; the rest are ``details``."""


def read_record(path: Path) -> RunRecord:
    """The :class:`RunRecord` in ``path``: the one reader. InputError, one line naming
    the file, the key and the value, for a record that is missing, not a regular file
    (a link or a FIFO is not opened), larger than :data:`MAX_RECORD_BYTES`, not JSON, or
    holding a value rigkit would not have written (a key missing, a number not finite
    or out of its range, text where a number belongs)."""
    data = _json(path)
    key = KeyPath(path)
    if not isinstance(data, dict):
        raise InputError(f"{path}: not a run's record (a JSON object expected)")
    top = key.mapping(data, required=_TYPED[3:],
                      optional=(*_TYPED[:3], *(k for k in data if k not in _TYPED)))
    rig_key = key.child("rig")
    rig_data = rig_key.mapping(top["rig"], required=("name", *(f.name for f in fields(
        RigGeometry))))
    frames = _frames(top["frames"], key.child("frames"))
    width, height = _size(top["image_size_px"], key.child("image_size_px"))
    camera_key = key.child("left_camera_px")
    camera = camera_key.mapping(top["left_camera_px"], required=("f", "cx", "cy"))
    targets_key = key.child("targets")
    return RunRecord(
        frames=frames,
        rig=_rig(rig_data, rig_key),
        settings=_settings(top["settings"], key.child("settings")),
        targets=tuple(target_from_data(value, targets_key.item(i))
                      for i, value in enumerate(targets_key.sequence(top["targets"]))),
        rig_name=rig_key.child("name").line(rig_data["name"]),
        image_size_px=(width, height),
        left_camera_px=(
            camera_key.child("f").bounded(camera["f"], "px", MAX_FOCAL_PX),
            _within(camera["cx"], camera_key.child("cx"), MAX_SIDE_PX, "px"),
            _within(camera["cy"], camera_key.child("cy"), MAX_SIDE_PX, "px"),
        ),
        lens=_lens(top["distortion_k1_k2_p1_p2_k3"], key.child("distortion_k1_k2_p1_p2_k3")),
        burst_length=key.child("burst_length").integer(top["burst_length"], "frames",
                                                       MAX_BURST),
        median_depth_m=_or_none(top["median_depth_m"], key.child("median_depth_m"),
                                lambda v, k: k.bounded(v, "m", MAX_RANGE_M)),
        offset_px=_within(top["disparity_offset_px"], key.child("disparity_offset_px"),
                          MAX_SIDE_PX, "px"),
        offset_sigma_px=_within(top["disparity_offset_sigma_px"],
                                key.child("disparity_offset_sigma_px"), MAX_SIDE_PX, "px",
                                low=0.0),
        offset_depth_fraction=_or_none(
            top["offset_depth_error_fraction"], key.child("offset_depth_error_fraction"),
            lambda v, k: _within(v, k, 1.0, "(a share of depth)", low=0.0)),
        shortfalls=_lines(top["shortfalls"], key.child("shortfalls")),
        warnings=_lines(top["warnings"], key.child("warnings")),
        run_id=_or_none(top.get("run_id"), key.child("run_id"), lambda v, k: k.line(v)),
        time_utc=_or_none(top.get("time_utc"), key.child("time_utc"), lambda v, k: k.line(v)),
        rigkit_version=_or_none(top.get("rigkit_version"), key.child("rigkit_version"),
                                lambda v, k: k.line(v)),
        details={k: v for k, v in top.items() if k not in _TYPED},
    )


def session_record(session_path: Path) -> RunRecord | None:
    """The record of a session's newest run; None where it has no results (InputError
    where its record is refused, :func:`read_record`)."""
    path = RunFiles.of_session(session_path).record
    if not os.path.lexists(path):
        return None
    return read_record(path)


def _json(path: Path) -> Any:
    try:
        fd = open_regular(path, os.O_RDONLY)
    except FileNotFoundError:
        raise InputError(f"{path}: missing (written with the depth map)") from None
    except OSError as exc:
        raise InputError(f"{path}: cannot read ({exc.strerror})") from None
    with os.fdopen(fd, "rb") as handle:
        text = handle.read(MAX_RECORD_BYTES + 1)
    if len(text) > MAX_RECORD_BYTES:
        raise InputError(f"{path}: larger than a run's record can be ({MAX_RECORD_BYTES >> 20} "
                         "MB); not written by rigkit")
    try:  # NaN and Infinity are read as such, and refused where they stand
        return json.loads(text)
    except (ValueError, RecursionError) as exc:
        raise InputError(f"{path}: not a run's record ({str(exc)[:80]})") from None


def _within(value: Any, key: KeyPath, limit: float, unit: str, low: float | None = None
            ) -> float:
    """A finite number in [-limit, limit] (``low``: in [low, limit])."""
    number = key.number(value, unit)
    bottom = -limit if low is None else low
    if not bottom <= number <= limit:
        raise key.error(f"must be between {bottom:g} and {limit:g} {unit}", value)
    return number


def _or_none(value: Any, key: KeyPath, read: Any) -> Any:
    return None if value is None else read(value, key)


def _lines(value: Any, key: KeyPath) -> tuple[str, ...]:
    return tuple(key.item(i).text(v, strip=False) for i, v in enumerate(key.sequence(value)))


def _size(value: Any, key: KeyPath) -> tuple[int, int]:
    width, height = (key.integer(v, "pixels", MAX_SIDE_PX) for v in key.pair(value,
                                                                            "width, height"))
    return width, height


def _frames(value: Any, key: KeyPath) -> dict[str, tuple[RecordedFrame, ...]]:
    positions = key.mapping(value, required=POSITIONS)
    out = {}
    for position in POSITIONS:
        burst_key = key.child(position)
        frames = []
        for i, item in enumerate(burst_key.sequence(positions[position])):
            item_key = burst_key.item(i)
            frame = item_key.mapping(item, required=("file",), optional=("sha256",))
            sha = frame.get("sha256")
            frames.append(RecordedFrame(item_key.child("file").text(frame["file"]),
                                        None if sha is None else _sha256(sha, item_key)))
        out[position] = tuple(frames)
    return out


def _sha256(value: Any, key: KeyPath) -> str:
    text = key.child("sha256").line(value)
    if len(text) != 64 or any(c not in "0123456789abcdef" for c in text):
        raise key.child("sha256").error("must be a SHA-256 in hex", value)
    return text


def _rig(data: dict[str, Any], key: KeyPath) -> RigGeometry:
    lens = _lens(data["distortion"], key.child("distortion"))
    points_key = key.child("principal_points_px")
    points = points_key.sequence(data["principal_points_px"])
    if len(points) != 3:
        raise points_key.error("must list three (x, y) offsets", data["principal_points_px"])
    centres = tuple(
        tuple(_within(v, points_key.item(i), MAX_SIDE_PX, "px")
              for v in points_key.item(i).pair(p, "x, y"))
        for i, p in enumerate(points))
    one = data["one_camera"]
    if not isinstance(one, bool):
        raise key.child("one_camera").error("must be true or false", one)
    try:
        return RigGeometry(
            key.child("focal_px").bounded(data["focal_px"], "px", MAX_FOCAL_PX),
            key.child("baseline_lr_m").bounded(data["baseline_lr_m"], "m", MAX_RANGE_M),
            key.child("baseline_lb_m").bounded(data["baseline_lb_m"], "m", MAX_RANGE_M),
            lens, principal_points_px=centres, one_camera=one)  # type: ignore[arg-type]
    except InputError as exc:
        raise key.error(str(exc)) from None


def _lens(value: Any, key: KeyPath) -> Distortion:
    terms = [key.item(i).number(v, "") for i, v in enumerate(key.sequence(value))]
    if any(abs(t) > 1e6 for t in terms):
        raise key.error("must be a lens's coefficients (each within +-1e6)", value)
    try:
        return distortion_coefficients(terms)
    except ValueError as exc:
        raise key.error(str(exc), value) from None


def _settings(value: Any, key: KeyPath) -> PipelineSettings:
    names = [f.name for f in fields(PipelineSettings)]
    data = key.mapping(value, required=names)
    for name in names:
        number = key.child(name).number(data[name], "")
        if abs(number) > 1e9:
            raise key.child(name).error("must be a setting the pipeline takes", number)
    try:
        return PipelineSettings(**data)
    except (TypeError, ValueError) as exc:
        raise key.error(str(exc)) from None


def stale_results(session: Session, with_targets: bool = True) -> str | None:
    """Why a session's ``results/`` no longer show it, or None: what made the run
    (:class:`RunInputs`) differs from the session's now (with ``with_targets`` False:
    leaving out the targets, on which the depth map does not depend), or the record or
    the run's comparisons cannot be read (the line says why). None where there are no
    results."""
    try:
        record = session_record(session.path)
    except InputError as exc:
        return f"{exc}; process again"
    if record is None:
        return None
    changed = changed_inputs(record.inputs, session_inputs(session), with_targets)
    if changed:
        return f"results/ are from run {record.run_id or '?'}, before {changed}; process again"
    done = session_comparisons(session.path)
    if with_targets and os.path.lexists(done):
        try:
            read_rows(done)
        except InputError as exc:  # why, without the path: said by the caller
            return (f"results/{LOG_NAME} is unreadable ({str(exc).split(': ', 1)[-1]}); "
                    "process again")
    return None
