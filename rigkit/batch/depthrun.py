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

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from rigkit import __version__
from rigkit.capture.checks import capture_warnings
from rigkit.capture.frames import FrameFile, load_capture
from rigkit.capture.model import POSITIONS, Target
from rigkit.capture.results import (
    RecordedFrame,
    RunFiles,
    RunRecord,
)
from rigkit.core.files import Content
from rigkit.core.lazy import preload
from rigkit.pipeline import DepthResult, estimate_depth
from rigkit.pipeline.shimmer import Shimmer
from rigkit.rig.bursts import burst_warning
from rigkit.rig.profile import RigProfile

Progress = Callable[[str, float], None]


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

    def record(self, targets: Sequence[Target] = (), run_id: str | None = None,
               time_utc: str | None = None) -> RunRecord:
        """The run's :class:`~rigkit.capture.results.RunRecord` (``depth.json``), with
        the laser ``targets`` it was compared with and, for a processing run, its
        ``run_id`` and ``time_utc``."""
        result = self.result
        fraction = result.offset_depth_fraction
        diagnostics = result.diagnostics()
        return RunRecord(
            frames={pos: tuple(RecordedFrame(f.shown, f.sha256) for f in burst)
                    for pos, burst in self.bursts.items()},
            rig=self.profile.geometry(),
            settings=result.settings,
            targets=tuple(targets),
            rig_name=self.profile.name,
            image_size_px=self.size,
            left_camera_px=self.left_camera_px(),
            lens=result.distortion,
            burst_length=self.burst_length,
            median_depth_m=result.median_depth_m if math.isfinite(result.median_depth_m)
            else None,
            offset_px=result.ambiguity.offset_px,
            offset_sigma_px=result.ambiguity.offset_sigma_px,
            offset_depth_fraction=fraction if math.isfinite(fraction) else None,
            shortfalls=self.shortfalls,
            warnings=self.warnings,
            run_id=run_id,
            time_utc=time_utc,
            rigkit_version=__version__ if run_id is not None else None,
            details={**diagnostics, "shimmer": {"frames": self.shimmer[1],
                                                **self.shimmer[0].as_dict()}
                     if self.shimmer else None},
        )

    def left_camera_px(self) -> tuple[float, float, float]:
        """(f, cx, cy) px: the left view's focal length and principal point as the run
        took them, pixel centres at integers: the centre the lens fit gave the left view
        (:attr:`rigkit.pipeline.distortion.LensFit.centres_px`), else the rig profile's
        (:meth:`rigkit.rig.profile.RigProfile.intrinsics`)."""
        camera = self.profile.intrinsics(self.size)
        fit = self.result.lens_fit
        if fit is None:
            return camera.focal_px, camera.cx_px, camera.cy_px
        (width, height), (dx, dy) = self.size, fit.centres_px[0]
        return camera.focal_px, (width - 1) / 2 + dx, (height - 1) / 2 + dy

    @property
    def size(self) -> tuple[int, int]:
        """The depth map's (W, H), px."""
        return self.left.shape[1], self.left.shape[0]

    def outputs(self, files: RunFiles, record: RunRecord) -> dict[str, Content]:
        """What the run writes, by file name (``files``' names, in one folder): depth,
        sigma, grey, flags and ``record``."""
        result = self.result
        return {files.depth.name: result.depth, files.sigma.name: result.sigma,
                files.grey.name: self.left_grey(), files.flags.name: result.flags(),
                files.record.name: record.to_json()}

    def left_grey(self) -> np.ndarray:
        """The left image the depth map lies on as (H, W) uint8 grey, for the point
        colours of ``rigkit export`` (``grey.png`` beside the depth map)."""
        return np.clip(np.rint(self.left), 0, 255).astype(np.uint8)


def run_depth(
    bursts: Mapping[str, Sequence[FrameFile]],
    rig: RigProfile,
    *,
    cache_dir: Path | None = None,
    force: bool = False,
    progress: Progress | None = None,
    size_from: str | None = None,
) -> DepthRun:
    """Depth of the left view from a capture (position -> its frames, oldest first) and
    its rig profile, whose image size every frame must have (``size_from`` says where
    that size came from, for messages: "the left frame a.png is"; default the profile).
    ``cache_dir`` keeps decoded RAW frames by content hash; ``force`` runs despite a
    fatal EXIF finding. RigkitError (one line) for a capture that cannot give a
    trustworthy depth map."""
    report = progress or (lambda stage, fraction: None)
    # The pipeline's fits need SciPy's optimisers: imported while the frames decode.
    preload("scipy.optimize")
    firsts = {pos: bursts[pos][0].path for pos in POSITIONS if bursts.get(pos)}
    warnings = capture_warnings(rig, firsts, force)  # a wrong zoom stops before decoding
    loaded = load_capture(bursts, rig.image_size, cache_dir, f"rig profile {rig.name}",
                          size_from)
    report("reading frames", 0.1)
    geometry = rig.geometry()
    result = estimate_depth(
        *loaded.images, geometry, settings=rig.pipeline_settings(),
        progress=lambda stage, f: report(stage, 0.1 + 0.8 * f),
    )
    length = min(len(bursts[pos]) for pos in POSITIONS)
    found = [result.relief_warning(), result.offset_warning(length)]
    if loaded.shimmer is not None:
        found.append(burst_warning(rig, *loaded.shimmer, result.median_depth_m, length))
    shortfalls = tuple(filter(None, found))
    if result.lens_fit is not None and (lens_note := result.lens_fit.warning()):
        warnings = (*warnings, lens_note)
    return DepthRun(
        result=result,
        left=loaded.images[0],
        profile=rig,
        bursts={pos: tuple(bursts[pos]) for pos in POSITIONS},
        shimmer=loaded.shimmer,
        burst_length=length,
        warnings=(*warnings, *shortfalls),
        shortfalls=shortfalls,
    )
