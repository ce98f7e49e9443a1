"""The depth pipeline, in the order of the paper's Algorithm 1."""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field, replace

import numpy as np

from rigkit.core.threads import ViewPool, deterministic
from rigkit.errors import InputError, PipelineError
from rigkit.geometry import NO_DISTORTION, Distortion
from rigkit.pipeline.agreement import view_agreement
from rigkit.pipeline.ambiguity import Ambiguity, remove_ambiguity
from rigkit.pipeline.checks import Parallax, check_distinct, check_parallax, check_roles
from rigkit.pipeline.depth import to_left
from rigkit.pipeline.distortion import LensFit, refine_lens, three_view_tracks
from rigkit.pipeline.features import Matches, match_all
from rigkit.pipeline.lens import Lens
from rigkit.pipeline.motion import BackStart, back_view_start, rig_motion
from rigkit.pipeline.rectify import (
    Rectification,
    apply_homography,
    footprints,
    pseudo_rectify,
    scaling,
    warp_pair,
)
from rigkit.pipeline.rig import RigGeometry
from rigkit.pipeline.settings import PipelineSettings
from rigkit.pipeline.stereo import (
    SGBM,
    StereoMatcher,
    clipped_black,
    fill_holes,
    restrict_to_footprints,
    surface_mask,
)


@dataclass(frozen=True)
class DepthResult:
    """Output of :func:`estimate_depth`.

    depth: (H, W) float32, metres, z in the left camera frame, original left pixel grid,
    NaN where there is no estimate. sigma: (H, W) float32, metres, one standard error of
    that depth (disparity noise and offset uncertainty combined; larger where a hole was
    filled from its background neighbour); NaN where no depth. filled: (H, W) bool,
    pixels whose depth comes from hole filling rather than a match. no_surface: (H, W)
    bool, pixels with nothing to match (sky, blank or clipped areas): NaN in depth.
    disagree: (H, W) bool, pixels whose depth the right or back view contradicted
    (something moved between the captures; :mod:`rigkit.pipeline.agreement`), with a
    margin around them: NaN in depth.
    ``distortion``: the lens the depth went through (OpenCV ``k1, k2, p1, p2, k3``);
    ``lens_fit``: how it was fitted from the views (None: taken as given).
    ``median_depth_m``: the median of ``depth`` (NaN where there is none);
    ``offset_depth_fraction``: the relative depth error (one sigma, unitless) that the
    disparity offset's uncertainty alone leaves at that depth; it is the same for
    every pixel of that depth, so averaging over pixels does not reduce it.
    ``parallax``: the left/right disparities' spread (:class:`~rigkit.pipeline.checks.
    Parallax`; a nearly flat scene: :meth:`relief_warning`).
    """

    depth: np.ndarray
    sigma: np.ndarray
    filled: np.ndarray
    no_surface: np.ndarray
    disagree: np.ndarray
    rectification: Rectification
    ambiguity: Ambiguity
    disparity: np.ndarray
    disparity_scale: float
    matches_lr: int
    matches_lb: int
    settings: PipelineSettings = field(default_factory=PipelineSettings)
    distortion: Distortion = NO_DISTORTION
    lens_fit: LensFit | None = None
    timings_s: dict[str, float] = field(default_factory=dict)
    median_depth_m: float = float("nan")
    offset_depth_fraction: float = float("nan")
    parallax: Parallax | None = None

    def flags(self) -> np.ndarray:
        """(H, W) uint8, what each pixel's depth rests on, as bits (``FLAG_*``): matched
        (1), filled from a neighbour (2), nothing to match (4), views disagree (8); 0
        where there is no depth for another reason (outside the right view)."""
        known = np.isfinite(self.depth)
        out = np.multiply(known, FLAG_MATCHED, dtype=np.uint8)  # in place from here on
        np.copyto(out, np.uint8(FLAG_FILLED), where=self.filled & known)
        np.bitwise_or(out, np.uint8(FLAG_NO_SURFACE), out=out, where=self.no_surface)
        np.bitwise_or(out, np.uint8(FLAG_DISAGREE), out=out, where=self.disagree)
        return out

    def offset_warning(self, frames: int = 1) -> str | None:
        """See :func:`offset_warning`; ``frames`` per position were stacked."""
        return offset_warning(self.offset_depth_fraction, self.offset_sources(), frames)

    def relief_warning(self) -> str | None:
        """One line where the scene is nearly flat (:meth:`Parallax.little_relief`)."""
        return self.parallax.little_relief() if self.parallax is not None else None

    def offset_sources(self) -> dict[str, float]:
        """What the disparity offset's standard error is made of (px, one sigma each,
        adding in quadrature to ``ambiguity.offset_sigma_px``): ``air``, the matches'
        scatter between parts of the frame and large-scale shimmer; ``principal_points``,
        the views' unknown principal points (three cameras' prior, or one camera's
        fitted centre); ``lens``, the lens fitted from the views."""
        a, fit = self.ambiguity, self.lens_fit
        lens = fit.offset_sigma_px if fit is not None else 0.0
        centres = float(np.hypot(a.principal_point_sigma_px,
                                 fit.centre_offset_sigma_px if fit is not None else 0.0))
        known = centres**2 + lens**2
        return {"air": float(np.sqrt(max(a.offset_sigma_px**2 - known, 0.0))),
                "principal_points": centres, "lens": lens}

    def diagnostics(self) -> dict[str, object]:
        """JSON-ready summary: settings, warps, offset, match counts, timings."""
        r, a = self.rectification, self.ambiguity
        valid = np.isfinite(self.depth)
        return {
            "settings": self.settings.as_dict(),
            "distortion_k1_k2_p1_p2_k3": list(self.distortion),
            "lens_fit": self.lens_fit.as_dict() if self.lens_fit else None,
            "disparity_offset_px": a.offset_px,
            "disparity_offset_sigma_px": a.offset_sigma_px,
            "disparity_offset_sigma_principal_point_px": self.offset_sources()[
                "principal_points"],
            "disparity_offset_sigma_tilt_px": a.tilt_sigma_px,
            "offset_depth_error_fraction": self.offset_depth_fraction
            if np.isfinite(self.offset_depth_fraction)
            else None,
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
            "parallax_px": None if self.parallax is None else {
                "spread": self.parallax.spread_px, "noise": self.parallax.noise_px,
                "relief": self.parallax.relief_px},
            "density": float(valid.mean()),
            "no_surface_fraction": float(self.no_surface.mean()),
            "views_disagree_fraction": float(self.disagree.mean()),
            "depth_range_m": [float(np.nanmin(self.depth)), float(np.nanmax(self.depth))]
            if valid.any()
            else None,
            "median_depth_m": self.median_depth_m if np.isfinite(self.median_depth_m) else None,
            "timings_s": self.timings_s,
        }


Progress = Callable[[str, float], None]
FLAG_MATCHED, FLAG_FILLED, FLAG_NO_SURFACE, FLAG_DISAGREE = 1, 2, 4, 8
"""Bits of :meth:`DepthResult.flags` (``flags.npy`` in a session's results)."""
OFFSET_WARNING_FRACTION = 0.003
"""Above this relative depth error from the offset alone (one sigma) the result says
so: the field issue's bar for a scene's median bias, which bursts meet."""


OFFSET_ADVICE = {
    "air": ("the offset's scatter between parts of the frame, as this run measured it "
            "(heat shimmer where the air has any, else image noise and sparse matches): "
            "bursts of several frames per position and full-resolution frames reduce it "
            "(docs/field.md)"),
    "principal_points": ("the views' principal points, which may differ: one camera "
                         "moved between the three positions has one (rig profile: "
                         "one_camera: true; docs/rig-profiles.md)"),
    "lens": ("the lens distortion fitted from the views: give the lens in the rig "
             "profile (camera.distortion, or lensfun's profile; docs/rig-profiles.md)"),
}
"""What the user can do about each part of :meth:`DepthResult.offset_sources`."""


def offset_warning(
    offset_depth_fraction: float, sources: Mapping[str, float], frames: int = 1
) -> str | None:
    """One line for the user where the offset's uncertainty alone (``offset_depth_fraction``
    of :class:`DepthResult`) exceeds ``OFFSET_WARNING_FRACTION`` of depth, naming its
    largest part of ``sources`` (:meth:`DepthResult.offset_sources`) and what reduces
    it, with how many frames per position would (:func:`frames_for_offset`) where the
    air's part is the largest, the run having had ``frames``; else None."""
    if not offset_depth_fraction > OFFSET_WARNING_FRACTION:
        return None
    largest = max(OFFSET_ADVICE, key=lambda name: sources.get(name, 0.0))
    line = (f"the disparity offset alone leaves +-{100 * offset_depth_fraction:.2f} % "
            f"of depth (1 sigma) at the median range, most of it from {OFFSET_ADVICE[largest]}")
    needed = frames_for_offset(offset_depth_fraction, sources, frames)
    if largest == "air" and needed is not None:
        line += (f"; about {needed} frames per position would bring it to "
                 f"{100 * OFFSET_WARNING_FRACTION:.1f} % (the air's part falls as "
                 "1 / sqrt(frames))")
    return line


def frames_for_offset(
    offset_depth_fraction: float, sources: Mapping[str, float], frames: int
) -> int | None:
    """Frames per position under which the offset's uncertainty would stay within
    ``OFFSET_WARNING_FRACTION`` of depth, for a run with ``frames`` that left
    ``offset_depth_fraction`` made of ``sources`` (px; only ``air`` falls with frames,
    as 1 / sqrt(frames), the scatter of independent draws); None where the other parts
    alone exceed it, so that no number of frames would."""
    total_px = float(np.sqrt(sum(v**2 for v in sources.values())))
    if not total_px > 0:
        return None
    goal_px = OFFSET_WARNING_FRACTION / offset_depth_fraction * total_px
    room = goal_px**2 - (total_px**2 - sources.get("air", 0.0) ** 2)
    if room <= 0:
        return None
    return max(frames + 1, math.ceil(frames * sources.get("air", 0.0) ** 2 / room))


def _check_sizes(left: np.ndarray, right: np.ndarray, back: np.ndarray) -> None:
    if not (left.shape == right.shape == back.shape):
        sizes = ", ".join(
            f"{n} {a.shape[1]}x{a.shape[0]}"
            for n, a in (("left", left), ("right", right), ("back", back))
        )
        raise InputError(f"images differ in size ({sizes}); all three must match")


@deterministic
def estimate_depth(
    left: np.ndarray,
    right: np.ndarray,
    back: np.ndarray,
    rig: RigGeometry,
    matcher: StereoMatcher | None = None,
    progress: Progress | None = None,
    settings: PipelineSettings | None = None,
) -> DepthResult:
    """Dense metric depth of the left view from three (H, W) float32 grey images, for
    the ``rig`` (what is known of it) under ``settings`` (default
    :class:`PipelineSettings`, every tunable number; the rig's facts are never there).
    ``progress(stage, fraction)`` is called as stages finish.
    """
    _check_sizes(left, right, back)
    s = settings or PipelineSettings()
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

    size = (left.shape[1], left.shape[0])
    # The left image prepared once for both pairs, the views' work in parallel.
    raw_lr, raw_lb = match_all(left, [(right, "left/right"), (back, "left/back")], s)
    check_distinct(left, right, back)  # after matching: a blank scene says so first
    given = Lens(rig.focal_px, size, rig.distortion)
    right_motion, back_motion = rig_motion(raw_lr, raw_lb, rig.focal_px, given.centre,
                                           three_view_tracks(raw_lr, raw_lb))
    check_roles(right_motion.scale, back_motion.scale, rig.baseline_lb_m)
    start = back_view_start(back_motion, rig.baseline_lb_m)
    lap("matching", 0.2)
    (lens, right_lens, back_lens), lens_fit = _lenses(raw_lr, raw_lb, rig, size, s, start)
    if lens_fit is not None:
        lap("lens", 0.25)
    m_lr, m_lb = _ideal(raw_lr, lens, right_lens), _ideal(raw_lb, lens, back_lens)
    rect = pseudo_rectify(m_lr, rig.focal_px, size, s, lens)
    parallax = check_parallax(m_lr, rect)
    scale = s.stereo_scale
    rl, rr = warp_pair(left, right, rect, scale, lens, right_lens)
    lap("rectification", 0.35)
    lo, hi = rect.disparity_range
    rng = (int(np.floor(lo * scale)), int(np.ceil(hi * scale)))
    with ViewPool() as pool:  # the masks are found while the pair is matched
        matched = pool.submit(matcher, rl, rr, rng)
        left_fp, right_fp = footprints(rect, size, scale, lens=lens, right_lens=right_lens)
        surface = surface_mask(rl, left_fp, s.min_texture, s.texture_window_px)
        disparity = matched.result()
    disparity = restrict_to_footprints(np.where(surface, disparity, np.nan), left_fp, right_fp)
    lap("stereo", 0.75)
    amb = remove_ambiguity(m_lb, disparity, scale, rect, rig, s, start)
    lap("ambiguity", 0.8)
    agree = view_agreement(rl, rr, back, disparity, scale, rect, amb, back_lens, rig, s)
    if agree.disagree.any():
        disparity = np.where(agree.disagree, np.nan, disparity).astype(np.float32)
        if _touches(m_lb, agree.disagree, rect, scale):
            amb = _without_disagreeing(amb, m_lb, disparity, scale, rect, rig, s, start)
    lap("agreement", 0.85)
    if lens_fit is not None:  # the lens and one camera's centre, fitted, move the offset too
        offset_sigma = float(np.sqrt(amb.offset_sigma_px**2 + lens_fit.offset_sigma_px**2
                                     + lens_fit.centre_offset_sigma_px**2))
        amb = replace(amb, offset_sigma_px=offset_sigma)
    dense, holes = fill_holes(disparity, s.fill_max_gap_px, barrier=agree.disagree)
    # Holes filled across a footprint edge would extrapolate into unseen ground, and
    # a hole with no surface in it (sky between two buildings) is no occlusion.
    dense = restrict_to_footprints(np.where(surface, dense, np.nan), left_fp, right_fp)
    holes &= np.isfinite(dense)
    depth, (filled, no_surface, disagree) = to_left(
        dense, (holes, ~surface & left_fp, agree.disagree & left_fp), scale, rect, amb.beta,
        rig.baseline_lr_m, left.shape, lens,
    )
    black = clipped_black(left)  # the canvas is too coarse to see it: stereo.clipped_black
    if black.any():
        depth[black] = np.nan
        no_surface |= black
        filled &= ~black
    sigma = _depth_sigma(depth, filled, rig, amb, s)
    known = depth[np.isfinite(depth)]  # np.nanmedian's value, at half its cost
    z_median = float(np.median(known)) if known.size else float("nan")
    offset_fraction = z_median * amb.offset_sigma_px / (rig.focal_px * rig.baseline_lr_m)
    lap("depth", 1.0)
    return DepthResult(
        depth=depth,
        sigma=sigma,
        filled=filled,
        no_surface=no_surface,
        disagree=disagree,
        rectification=rect,
        ambiguity=amb,
        disparity=disparity,
        disparity_scale=scale,
        matches_lr=len(m_lr.left),
        matches_lb=len(m_lb.left),
        settings=s,
        distortion=lens.distortion,
        lens_fit=lens_fit,
        timings_s=timings,
        median_depth_m=z_median,
        offset_depth_fraction=offset_fraction,
        parallax=parallax,
    )


def _lenses(
    raw_lr: Matches, raw_lb: Matches, rig: RigGeometry, size: tuple[int, int],
    s: PipelineSettings, start: BackStart | None = None,
) -> tuple[tuple[Lens, Lens, Lens], LensFit | None]:
    """The lens the later stages use, as each view (left, right, back) sees it: the
    given one, refined from the views unless ``s.distortion_terms`` is 0, each view
    bent about its own centre: fitted (:mod:`rigkit.pipeline.distortion`, from
    ``start``: :func:`~rigkit.pipeline.motion.back_view_start`), else the rig's
    principal point for it."""
    given = Lens(rig.focal_px, size, rig.distortion)
    if not s.distortion_terms:
        left, right, back = (Lens(rig.focal_px, size, rig.distortion, centre)
                             for centre in rig.principal_points_px)
        return (left, right, back), None
    rectified = pseudo_rectify(_ideal(raw_lr, given), rig.focal_px, size, s)
    fit = refine_lens(raw_lr, raw_lb, rectified, given, rig, s, start)
    return (fit.lens(rig.focal_px, size, 0), fit.lens(rig.focal_px, size, 1),
            fit.lens(rig.focal_px, size, 2)), fit


def _touches(m: Matches, mask: np.ndarray, rect: Rectification, scale: float) -> bool:
    """Whether any of the matches' left points (ideal px) falls on ``mask`` (h, w) bool
    of the ``scale``-resized rectified canvas."""
    xs = np.rint(apply_homography(scaling(scale) @ rect.H_left, m.left)).astype(int)
    h, w = mask.shape
    inside = (xs[:, 0] >= 0) & (xs[:, 0] < w) & (xs[:, 1] >= 0) & (xs[:, 1] < h)
    return bool(mask[xs[inside, 1], xs[inside, 0]].any())


def _without_disagreeing(
    amb: Ambiguity, m_lb: Matches, disparity: np.ndarray, scale: float,
    rect: Rectification, rig: RigGeometry, s: PipelineSettings, start: BackStart,
) -> Ambiguity:
    """Ambiguity removal again, on the ``disparity`` without the pixels where the views
    disagree: what moved between the captures must not pull the offset. Where too few
    back-view matches remain for that, the first fit ``amb`` stands (its robust loss
    has already discounted the matches that fit no single pose)."""
    try:
        return remove_ambiguity(m_lb, disparity, scale, rect, rig, s, start)
    except PipelineError:
        return amb


def _ideal(m: Matches, lens: Lens, other_lens: Lens | None = None) -> Matches:
    """``m`` with both sides moved from recorded to ideal pinhole pixels, the left one
    through ``lens``, the other view's through ``other_lens`` (None: ``lens``)."""
    other_lens = other_lens or lens
    if lens.identity and other_lens.identity:
        return m
    return replace(m, left=lens.to_ideal(m.left), other=other_lens.to_ideal(m.other))


def _depth_sigma(
    depth: np.ndarray, filled: np.ndarray, rig: RigGeometry, amb: Ambiguity, s: PipelineSettings
) -> np.ndarray:
    """First-order error: dz = z^2 / (f C_lr) * sqrt(dd_stereo^2 + dd_offset^2).
    dd takes one of two values (matched or filled); computed in float32 and in place,
    since each fresh image-sized array costs time to map in."""
    dd = np.hypot(np.array([s.stereo_noise_px, s.filled_noise_px]) / s.stereo_scale,
                  amb.offset_sigma_px) / (rig.focal_px * rig.baseline_lr_m)
    sigma = np.square(depth, dtype=np.float32)
    np.multiply(sigma, np.float32(dd[0]), out=sigma, where=~filled)  # in place
    np.multiply(sigma, np.float32(dd[1]), out=sigma, where=filled)
    return sigma
