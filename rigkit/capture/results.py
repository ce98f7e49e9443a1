"""A processing run's results in a session: its record (``results/depth.json``) and
whether they still show the session."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from rigkit.capture.comparisons import LOG_NAME, read_rows
from rigkit.capture.model import POSITIONS, RESULTS_DIR, Session
from rigkit.core.safefs import read_regular
from rigkit.errors import InputError


def run_metadata(session_path: Path) -> dict[str, Any] | None:
    """The latest run's ``results/depth.json`` as a mapping; None where the session has
    none that can be read (missing, damaged, or a link or FIFO, which are not opened)."""
    try:
        meta = json.loads(read_regular(session_path / RESULTS_DIR / "depth.json"))
    except (OSError, ValueError, InputError):
        return None
    return meta if isinstance(meta, dict) else None


def stale_results(session: Session, with_targets: bool = True) -> str | None:
    """Why ``results/`` no longer shows this session (frames, rig or, ``with_targets``,
    targets changed since the run that wrote it), or None. Without the targets: whether
    its depth map is still this session's (the depth does not depend on them)."""
    meta_path = session.path / RESULTS_DIR / "depth.json"
    if not meta_path.is_file():
        return None
    meta = run_metadata(session.path)
    if meta is None:  # damaged, a link or a FIFO
        return "results/depth.json is unreadable; process again"
    try:
        recorded = {pos: [f.get("sha256") for f in meta["frames"][pos]] for pos in POSITIONS}
    except (KeyError, TypeError, AttributeError):
        return "results/depth.json is unreadable; process again"
    current = {pos: [f.sha256 for f in session.bursts.get(pos, ())] for pos in POSITIONS}
    run = meta.get("run_id", "?")
    if recorded != current:
        return f"results/ are from run {run}, before the frames changed; process again"
    rig, used = session.rig().geometry(), meta.get("rig") or {}
    now = {"focal_px": rig.focal_px, "baseline_lr_m": rig.baseline_lr_m,
           "baseline_lb_m": rig.baseline_lb_m, "one_camera": rig.one_camera}
    if any(used.get(key, value) != value for key, value in now.items()):
        return f"results/ are from run {run}, before the rig changed; process again"
    if not with_targets:
        return None
    done = session.path / RESULTS_DIR / LOG_NAME
    try:
        rows = read_rows(done) if done.is_file() else []
    except InputError:
        return f"results/{LOG_NAME} is unreadable; process again"
    compared = {(r.target, r.u, r.v, r.laser_readings) for r in rows}
    targets = {(t.name, t.pixel[0], t.pixel[1], len(t.readings)) for t in session.targets}
    if compared != targets:
        return f"results/ are from run {run}, before the targets changed; process again"
    return None
