"""One depth run: a capture's frames and its rig in; depth, sigma, what to warn about
and what to record out.

``rigkit depth``, ``rigkit process`` and ``rigkit field`` all compute depth through
:func:`run_depth`, so a capture gets the same frames, checks, warnings and
``depth.json`` whichever of them runs it:

1. the frames are decoded, checked and stacked (:func:`rigkit.capture.frames.
   load_capture`: RAW through LibRaw, a picture in every frame, one file per frame,
   the rig's image size);
2. the left, right and back frames' EXIF is checked against each other and the rig
   (:func:`rigkit.capture.checks.capture_warnings`; a different focal length stops
   the run unless forced);
3. the depth method runs (:func:`rigkit.pipeline.estimate_depth`; it refuses views
   without parallax, with the back view not magnified, or with right and back swapped);
4. what the result leaves uncertain becomes warnings: the disparity offset's share of
   depth error, and a burst shorter than the measured heat shimmer calls for.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from rigkit.capture.checks import capture_warnings
from rigkit.capture.frames import FrameFile, load_capture
from rigkit.capture.session import POSITIONS
from rigkit.core.lazy import preload
from rigkit.pipeline import DepthResult, estimate_depth
from rigkit.pipeline.shimmer import Shimmer
from rigkit.rig.bursts import burst_warning
from rigkit.rig.profile import RigProfile

Progress = Callable[[str, float], None]
RigAtSize = Callable[[tuple[int, int]], RigProfile]
"""A rig whose profile depends on the frames' size (one given by command-line values)."""


@dataclass(frozen=True)
class DepthRun:
    """What :func:`run_depth` found. ``left``: the left image the depth map lies on,
    (H, W) float32 grey in [0, 255]; ``burst_length``: frames per position (the
    shortest burst); ``warnings``: one line each, for the user and depth.json;
    ``shortfalls``: those of them that say the capture misses the goal (the disparity
    offset alone leaves more than 0.3 % of depth; a burst shorter than the measured
    shimmer calls for), which keep a verdict from saying "done"."""

    result: DepthResult
    left: np.ndarray
    profile: RigProfile
    bursts: Mapping[str, tuple[FrameFile, ...]]
    shimmer: tuple[Shimmer, str] | None
    burst_length: int
    warnings: tuple[str, ...]
    shortfalls: tuple[str, ...] = ()

    def metadata(self) -> dict[str, Any]:
        """The run as JSON-ready data (the body of ``depth.json``): frames, rig,
        warnings, shimmer, and the pipeline's diagnostics."""
        rig = self.profile.geometry()
        camera = self.profile.intrinsics((self.left.shape[1], self.left.shape[0]))
        return {
            "frames": {pos: [_frame_meta(f) for f in self.bursts[pos]] for pos in POSITIONS},
            "burst_length": self.burst_length,
            "image_size_px": [self.left.shape[1], self.left.shape[0]],
            "rig": {"name": self.profile.name, "focal_px": rig.focal_px,
                    "baseline_lr_m": rig.baseline_lr_m, "baseline_lb_m": rig.baseline_lb_m,
                    "distortion_k1_k2_p1_p2_k3": list(rig.distortion),
                    "one_camera": rig.one_camera,
                    "principal_points_px": [list(p) for p in rig.principal_points_px]},
            # Back-projection of the depth map (rigkit export), pixel centres at integers.
            "left_camera_px": {"f": camera.focal_px, "cx": camera.cx_px, "cy": camera.cy_px},
            "warnings": list(self.warnings),
            "shortfalls": list(self.shortfalls),
            "shimmer": {"frames": self.shimmer[1], **self.shimmer[0].as_dict()}
            if self.shimmer else None,
            **self.result.diagnostics(),
        }


    def left_grey(self) -> np.ndarray:
        """The left image the depth map lies on as (H, W) uint8 grey, for the point
        colours of ``rigkit export`` (``grey.png`` beside the depth map)."""
        return np.clip(np.rint(self.left), 0, 255).astype(np.uint8)


def _frame_meta(frame: FrameFile) -> dict[str, str]:
    meta = {"file": frame.shown}
    if frame.sha256:
        meta["sha256"] = frame.sha256
    return meta


def run_depth(
    bursts: Mapping[str, Sequence[FrameFile]],
    rig: RigProfile | RigAtSize,
    *,
    cache_dir: Path | None = None,
    force: bool = False,
    progress: Progress | None = None,
) -> DepthRun:
    """Depth of the left view from a capture (position -> its frames, oldest first) and
    its rig: a profile, whose image size every frame must have, or a function giving
    the profile for the frames' size. ``cache_dir`` keeps decoded RAW frames by content
    hash; ``force`` runs despite a fatal EXIF finding. RigkitError (one line) for a
    capture that cannot give a trustworthy depth map."""
    report = progress or (lambda stage, fraction: None)
    # The pipeline's fits need SciPy's optimisers: imported while the frames decode.
    preload("scipy.optimize")
    firsts = {pos: bursts[pos][0].path for pos in POSITIONS if bursts.get(pos)}
    if isinstance(rig, RigProfile):  # EXIF first: a wrong zoom stops before decoding
        warnings = capture_warnings(rig, firsts, force)
        loaded = load_capture(bursts, rig.image_size, cache_dir, f"rig profile {rig.name}")
        profile = rig
    else:
        loaded = load_capture(bursts, None, cache_dir)
        profile = rig(loaded.size)
        warnings = capture_warnings(profile, firsts, force)
    report("reading frames", 0.1)
    geometry = profile.geometry()
    result = estimate_depth(
        *loaded.images, geometry, settings=profile.pipeline_settings(),
        progress=lambda stage, f: report(stage, 0.1 + 0.8 * f),
    )
    length = min(len(bursts[pos]) for pos in POSITIONS)
    found = [result.relief_warning(), result.offset_warning(length)]
    if loaded.shimmer is not None:
        found.append(burst_warning(profile, *loaded.shimmer, result.median_depth_m, length))
    shortfalls = tuple(filter(None, found))
    if result.lens_fit is not None and (lens_note := result.lens_fit.warning()):
        warnings = (*warnings, lens_note)
    return DepthRun(
        result=result,
        left=loaded.images[0],
        profile=profile,
        bursts={pos: tuple(bursts[pos]) for pos in POSITIONS},
        shimmer=loaded.shimmer,
        burst_length=length,
        warnings=(*warnings, *shortfalls),
        shortfalls=shortfalls,
    )
