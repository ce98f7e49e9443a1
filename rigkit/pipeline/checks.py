"""Refusing captures that cannot give depth, before they give a wrong one.

Depth comes from two differences between the views: the parallax between left and
right (points at different depths shift by different amounts) and the magnification
of the back view. A capture without one of them - the same frame given twice, a
tripod that was not moved - still matches perfectly, and the later stages would turn
it into a smooth, plausible, wrong depth map. Each check names what is wrong and what
to redo.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from rigkit.errors import PipelineError
from rigkit.pipeline.features import Matches
from rigkit.pipeline.rectify import Rectification, apply_homography

MIN_PARALLAX_PX = 0.5
"""Depth relief below which a scene is called nearly flat: the spread (5th to 95th
percentile) of the matches' rectified disparities beyond their noise, full-resolution
px (a scene whose depths span 1.6 % at 300 m, seen 2 m apart at f = 14,650 px, spreads
them over 1.6 px and gives 98.8 % of its pixels within 1 %). Less is no refusal: the
back view's magnification gives the range of a flat scene too; the run says so."""
NOISE_SPAN = 3.29
"""The 5th to 95th percentile span of a normal distribution, in standard deviations."""
TRACKING_FLOOR_PX = 0.01
"""Least RMS error credited to sub-pixel tracks, px of the images matched: noise-free
rendered views leave row residuals far below what tracking can promise."""
CLEAR_OF_NOISE = 1.5
"""Disparities must spread this many times what the matches' own noise spreads them
for the right view to count as seen from elsewhere: a camera only turned spreads them
0.75-1.2 times that (rendered views at 1536 and 4608 px, without and with heat shimmer);
relief adds to noise in quadrature, so field scenes whose disparities spread 3.4 and
5.0 px under shimmer spreading them 1.3 and 1.8 px stand 2.7 times clear."""
MAX_IMPLIED_RANGE_M = 50_000.0  # beyond this, the back view shows no magnification
NO_MAGNIFICATION_SIGMAS = 3.0
"""A magnification within this many standard errors of none is none."""
MAX_RIGHT_SCALE_CHANGE = 0.01
"""Left and right views are at the same distance: a larger scale change is zoom."""


def roles_problem(right: float, back: float, baseline_lb_m: float) -> str | None:
    """Why views of scale ``right`` and ``back`` (each against the left view) look like
    the back and the right view given the wrong way round, or None. The back camera,
    C_lb behind, sees the scene smaller by C_lb / (z + C_lb); the right one, beside the
    left, at the same size. A right view smaller than the back one, by a magnification
    that puts the scene at a plausible range (:func:`implied_range_m`), was taken
    behind."""
    if right >= back or implied_range_m(right, baseline_lb_m) > MAX_IMPLIED_RANGE_M:
        return None
    return (f"the right view is {right:.5f}x the left one and the back view {back:.5f}x: "
            "the right frame looks like the one taken behind; were right and back swapped?")


def check_roles(right: float, back: float, baseline_lb_m: float) -> None:
    """PipelineError when views of scale ``right`` and ``back`` against the left one
    (:attr:`rigkit.pipeline.motion.ViewMotion.scale`: at the matches' mean depth, their
    depths' parallax taken out) look swapped (:func:`roles_problem`), the back view
    shows no magnification (:func:`check_magnification`), or the right one is zoomed."""
    problem = roles_problem(right, back, baseline_lb_m)
    if problem is not None:
        raise PipelineError(problem)
    check_magnification(back, baseline_lb_m)
    if abs(right - 1.0) > MAX_RIGHT_SCALE_CHANGE:
        raise PipelineError(
            f"the right view is {right:.4f}x the left one: the zoom changed between them "
            "(set it back to the left frame's and take the right frame again)"
        )


def implied_range_m(scale: float, baseline_lb_m: float) -> float:
    """The range (m) at which a view ``baseline_lb_m`` behind is ``scale`` times the left
    view's size: z = m C_lb / (1 - m); inf when m >= 1."""
    if scale >= 1.0:
        return math.inf
    return baseline_lb_m * scale / (1.0 - scale)


def check_distinct(left: np.ndarray, right: np.ndarray, back: np.ndarray) -> None:
    """PipelineError if two positions got the same image (pixel for pixel)."""
    views = {"left": left, "right": right, "back": back}
    names = list(views)
    for i, a in enumerate(names):
        for b in names[i + 1 :]:
            if np.array_equal(views[a], views[b]):
                raise PipelineError(
                    f"the {a} and {b} images are identical: the same frame was given for "
                    f"two positions (capture the {b} position again)"
                )


@dataclass(frozen=True)
class Parallax:
    """How much the left/right disparities vary across the scene, full-resolution px.

    ``spread_px``: 5th to 95th percentile of the matches' rectified disparities
    (``x_left - x_right``); ``noise_px``: the spread the matches' own noise alone would
    give (:data:`NOISE_SPAN` times the RMS of their row residuals after rectification,
    which only noise and shimmer leave). A camera only turned between the views leaves
    noise; depth relief seen from C_lr apart adds to it. A flat scene square to the view
    has no relief either, so a spread as small as noise cannot tell a tripod that was not
    moved from a flat scene; one clear of noise whose relief (:attr:`relief_px`) is under
    :data:`MIN_PARALLAX_PX` is a moved tripod before a scene with little depth, whose
    range the back view gives (:meth:`little_relief`).
    """

    spread_px: float
    noise_px: float

    @property
    def moved(self) -> bool:
        """Whether the views were taken from different places (spread clear of noise)."""
        return self.spread_px > CLEAR_OF_NOISE * self.noise_px

    @property
    def relief_px(self) -> float:
        """The spread less what noise explains (they add in quadrature), px."""
        return math.sqrt(max(0.0, self.spread_px**2 - self.noise_px**2))

    def problem(self) -> tuple[str, str] | None:
        """What is wrong (a message and what to redo), or None where the disparities
        spread clear of noise: the right frame was taken from elsewhere. The one rule
        of the on-site check (:mod:`rigkit.capture.field`) and of processing
        (:func:`check_parallax`). A scene with little relief is no problem: the back
        view's magnification gives its range (:meth:`little_relief`)."""
        if self.moved:
            return None
        return (f"no parallax: the disparities vary by {self.spread_px:.2f} px, no more "
                f"than the matches' noise ({self.noise_px:.2f} px): the tripod was not "
                "moved, or the same view was taken twice",
                "move the tripod by C_lr to the right of the left position and take the "
                "right frame again")

    def little_relief(self) -> str | None:
        """One line where the right frame moved but the scene's relief spreads the
        disparities by less than :data:`MIN_PARALLAX_PX` beyond noise: its range still
        comes from the back view's magnification (the paper's point), but depth
        differences within it are hardly resolved; else None."""
        if not self.moved or self.relief_px >= MIN_PARALLAX_PX:
            return None
        return (f"little depth in view: {self.relief_px:.2f} px of parallax across the scene "
                f"(under {MIN_PARALLAX_PX:g} px): its range comes from the back view's "
                "magnification, but depth differences within it are barely resolved (aim "
                "where near and far things share the view for relief)")


def measure_parallax(matches: Matches, rect: Rectification, reduction: float = 1.0
                     ) -> Parallax:
    """:class:`Parallax` of left/right ``matches`` under ``rect``; ``reduction``: full-
    resolution px per px of the images they were matched in (>= 1)."""
    xl = apply_homography(rect.H_left, matches.left)
    xr = apply_homography(rect.H_right, matches.other)
    lo, hi = np.percentile(xl[:, 0] - xr[:, 0], [5, 95])
    rows = xl[:, 1] - xr[:, 1]
    rows = rows[np.abs(rows) < 1.0]  # the inliers the rectification was fitted to
    rms = float(np.sqrt(np.mean(rows**2))) if rows.size else math.inf
    noise = NOISE_SPAN * max(rms, TRACKING_FLOOR_PX)
    return Parallax(float(hi - lo) * reduction, noise * reduction)


def check_parallax(matches: Matches, rect: Rectification) -> Parallax:
    """The left/right ``matches``' :class:`Parallax` under ``rect``; PipelineError where
    it shows that the right frame was not taken from elsewhere (:meth:`Parallax.problem`)."""
    parallax = measure_parallax(matches, rect)
    problem = parallax.problem()
    if problem is not None:
        message, redo = problem
        raise PipelineError(f"left/right: {message} ({redo})")
    return parallax


def check_magnification(scale: float, baseline_lb_m: float, sigma: float = 0.0) -> float:
    """The range (m) that the back view's magnification ``scale`` (< 1) implies at
    C_lb; PipelineError if there is no magnification (none beyond
    :data:`MAX_IMPLIED_RANGE_M`, or none clear of three times the scale's standard
    error ``sigma``), or it is the wrong way round."""
    if scale >= 1.0:
        raise PipelineError(
            f"left/back: the back view shows the scene {scale:.5f}x as large as the left "
            "view (expected < 1: was the back frame taken behind the left camera?)"
        )
    z = implied_range_m(scale, baseline_lb_m)
    if z <= MAX_IMPLIED_RANGE_M and 1.0 - scale <= NO_MAGNIFICATION_SIGMAS * sigma:
        raise PipelineError(
            f"no magnification between left and back clear of the matches' noise: the back "
            f"view is {scale:.5f} +- {sigma:.5f}x the left view (was the back frame taken "
            "from the left position? step back by C_lb and capture again)"
        )
    if z > MAX_IMPLIED_RANGE_M:
        raise PipelineError(
            f"no magnification between left and back: the back view is {scale:.6f}x the "
            f"left view, a range of {z / 1000:.0f} km at C_lb = {baseline_lb_m} m (was the "
            "back frame taken from the left position? step back by C_lb and capture again)"
        )
    return z
