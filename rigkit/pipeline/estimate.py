"""The depth pipeline, in the order of the paper's Algorithm 1."""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from rigkit.errors import InputError
from rigkit.pipeline.ambiguity import Ambiguity, remove_ambiguity
from rigkit.pipeline.depth import depth_map, mask_to_left
from rigkit.pipeline.features import Matches, match_views
from rigkit.pipeline.rectify import Rectification, footprints, pseudo_rectify, warp_pair
from rigkit.pipeline.stereo import SGBM, StereoMatcher, fill_holes, restrict_to_footprints


@dataclass(frozen=True)
class RigGeometry:
    """The only calibration the method needs: focal length (px) and two baselines (m)."""

    focal_px: float
    baseline_lr_m: float
    baseline_lb_m: float

    def __post_init__(self) -> None:
        for name in ("focal_px", "baseline_lr_m", "baseline_lb_m"):
            value = getattr(self, name)
            if not np.isfinite(value) or value <= 0:
                raise InputError(f"{name} must be a positive number, got {value!r}")


@dataclass(frozen=True)
class DepthResult:
    """Output of :func:`estimate_depth`.

    depth: (H, W) float32, metres, z in the left camera frame, original left pixel grid,
    NaN where there is no estimate. sigma: (H, W) float32, metres, one standard error of
    that depth (disparity noise and offset uncertainty combined; larger where a hole was
    filled from its background neighbour); NaN where no depth. filled: (H, W) bool,
    pixels whose depth comes from hole filling rather than a match.
    """

    depth: np.ndarray
    sigma: np.ndarray
    filled: np.ndarray
    rectification: Rectification
    ambiguity: Ambiguity
    disparity: np.ndarray
    disparity_scale: float
    matches_lr: int
    matches_lb: int
    timings_s: dict[str, float] = field(default_factory=dict)

    def diagnostics(self) -> dict[str, object]:
        """JSON-ready summary: warps, offset, match counts, timings."""
        r, a = self.rectification, self.ambiguity
        valid = np.isfinite(self.depth)
        return {
            "disparity_offset_px": a.offset_px,
            "disparity_offset_sigma_px": a.offset_sigma_px,
            "right_yaw_correction_rad": a.beta,
            "back_rotation_rotvec_rad": [float(x) for x in a.back_rotvec],
            "back_offset_m": list(a.back_offset_m),
            "back_reprojection_rms_px": a.rms_px,
            "matches": {
                "left_right": self.matches_lr,
                "left_right_inliers": r.inliers,
                "left_back": self.matches_lb,
                "left_back_used": a.matches_used,
                "left_back_inliers": a.inliers,
            },
            "rectification": {
                "H_left": r.H_left.tolist(),
                "H_right": r.H_right.tolist(),
                "canvas_size": list(r.size),
                "disparity_range_px": list(r.disparity_range),
                "row_rms_px": r.row_rms_px,
                "R_lr": r.R_lr.tolist(),
                "R_rect": r.R_rect.tolist(),
            },
            "density": float(valid.mean()),
            "depth_range_m": [float(np.nanmin(self.depth)), float(np.nanmax(self.depth))]
            if valid.any()
            else None,
            "timings_s": self.timings_s,
        }


Progress = Callable[[str, float], None]


def _check_sizes(left: np.ndarray, right: np.ndarray, back: np.ndarray) -> None:
    if not (left.shape == right.shape == back.shape):
        sizes = ", ".join(
            f"{n} {a.shape[1]}x{a.shape[0]}"
            for n, a in (("left", left), ("right", right), ("back", back))
        )
        raise InputError(f"images differ in size ({sizes}); all three must match")


def estimate_depth(
    left: np.ndarray,
    right: np.ndarray,
    back: np.ndarray,
    rig: RigGeometry,
    matcher: StereoMatcher | None = None,
    stereo_scale: float = 0.5,
    fill_max_gap: int = 64,
    progress: Progress | None = None,
) -> DepthResult:
    """Dense metric depth of the left view from three (H, W) float32 grey images.

    ``stereo_scale``: resolution of stereo matching relative to the input (0.5 = half,
    as in the paper). ``fill_max_gap``: widest hole (px at the stereo resolution) filled
    from its background neighbour; 0 disables. ``progress(stage, fraction)`` is called
    as stages finish.
    """
    _check_sizes(left, right, back)
    matcher = matcher or SGBM()
    timings: dict[str, float] = {}
    clock = time.perf_counter()
    report = progress or (lambda stage, frac: None)

    def lap(stage: str, frac: float) -> None:
        nonlocal clock
        now = time.perf_counter()
        timings[stage] = round(now - clock, 3)
        clock = now
        report(stage, frac)

    m_lr: Matches = match_views(left, right, "left/right")
    m_lb: Matches = match_views(left, back, "left/back")
    lap("matching", 0.2)
    rect = pseudo_rectify(m_lr, rig.focal_px, (left.shape[1], left.shape[0]))
    rl, rr = warp_pair(left, right, rect, stereo_scale)
    lap("rectification", 0.35)
    lo, hi = rect.disparity_range
    rng = (int(np.floor(lo * stereo_scale)), int(np.ceil(hi * stereo_scale)))
    disparity = matcher(rl, rr, rng)
    left_fp, right_fp = footprints(rect, (left.shape[1], left.shape[0]), stereo_scale)
    disparity = restrict_to_footprints(disparity, left_fp, right_fp)
    lap("stereo", 0.8)
    amb = remove_ambiguity(
        m_lb, disparity, stereo_scale, rect, rig.baseline_lr_m, rig.baseline_lb_m
    )
    lap("ambiguity", 0.85)
    dense, holes = fill_holes(disparity, fill_max_gap)
    # Holes filled across a footprint edge would extrapolate into unseen ground.
    dense = restrict_to_footprints(dense, left_fp, right_fp)
    holes &= np.isfinite(dense)
    depth = depth_map(dense, stereo_scale, rect, amb.beta, rig.baseline_lr_m, left.shape)
    filled = mask_to_left(holes, stereo_scale, rect, left.shape)
    sigma = _depth_sigma(depth, filled, rig, amb, stereo_scale)
    lap("depth", 1.0)
    return DepthResult(
        depth=depth,
        sigma=sigma,
        filled=filled,
        rectification=rect,
        ambiguity=amb,
        disparity=disparity,
        disparity_scale=stereo_scale,
        matches_lr=len(m_lr.left),
        matches_lb=len(m_lb.left),
        timings_s=timings,
    )


STEREO_NOISE_PX = 0.25  # typical sub-pixel matching error at the matching resolution
FILLED_NOISE_PX = 2.0  # a filled hole is only as good as its neighbour's surface


def _depth_sigma(
    depth: np.ndarray, filled: np.ndarray, rig: RigGeometry, amb: Ambiguity, scale: float
) -> np.ndarray:
    """First-order error: dz = z^2 / (f C_lr) * sqrt(dd_stereo^2 + dd_offset^2)."""
    stereo = np.where(filled, FILLED_NOISE_PX, STEREO_NOISE_PX) / scale
    dd = np.hypot(stereo, amb.offset_sigma_px).astype(np.float32)
    return depth.astype(np.float32) ** 2 * dd / np.float32(rig.focal_px * rig.baseline_lr_m)
