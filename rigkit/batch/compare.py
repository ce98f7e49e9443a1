"""Comparing a laser target with the depth map: one row of the comparisons log."""

from __future__ import annotations

import math

import numpy as np

from rigkit.capture.comparisons import (
    STATUS_NO_ESTIMATE,
    STATUS_NO_READING,
    STATUS_OK,
    Comparison,
)
from rigkit.capture.model import Session, Target
from rigkit.capture.session import utc_now
from rigkit.pipeline.lens import Lens
from rigkit.rangefinder.ranging import aperture_offset, range_on_ray

NEIGHBOURHOOD_WINDOWS = 9
"""The side, in windows, of the neighbourhood whose window-sized medians measure how
much a target's median scatters."""
MIN_BLOCKS = 12
"""Fewer window-sized blocks with depth than this around a target measure nothing."""
SCATTER_GAIN = 1.5
"""The window medians' scatter about their neighbourhood's quadratic, times this, is a
target's own sigma: on rendered scenes the scatter understated the medians' error against
the truth by 1.1-1.7x on clean scenes and 1.5-2.2x under shimmer, whose errors are
correlated beyond the neighbourhood (docs/results-log.md, "A calibration a surveyor
would sign"); the per-pixel sigma overstated it 2.4-5x on clean scenes."""


def median_scatter(depth: np.ndarray, u: float, v: float, window_px: int) -> float:
    """The relative one-sigma (a fraction) of the median depth over the ``window_px``
    square at pixel (u, v) of ``depth`` ((H, W) float32, metres, NaN where none),
    measured: the medians of the window-sized blocks of a NEIGHBOURHOOD_WINDOWS square
    around it, less the quadratic surface through them (the relief), scatter as the
    window's own median does, but for errors correlated beyond the neighbourhood (hence
    :data:`SCATTER_GAIN`). NaN where fewer than :data:`MIN_BLOCKS` blocks have depth."""
    height, width = depth.shape
    side = max(int(window_px), 1)
    half = NEIGHBOURHOOD_WINDOWS // 2
    cu, cv = round(u) - side // 2, round(v) - side // 2
    medians, xs, ys = [], [], []
    for i in range(-half, half + 1):
        for j in range(-half, half + 1):
            y0, x0 = cv + i * side, cu + j * side
            if y0 < 0 or x0 < 0 or y0 + side > height or x0 + side > width:
                continue
            block = depth[y0:y0 + side, x0:x0 + side]
            finite = block[np.isfinite(block)]
            if 2 * finite.size >= block.size:
                medians.append(float(np.median(finite)))
                xs.append(j)
                ys.append(i)
    if len(medians) < MIN_BLOCKS:
        return math.nan
    z, x, y = np.array(medians), np.array(xs, float), np.array(ys, float)
    design = np.column_stack([np.ones_like(x), x, y, x * x, y * y, x * y])
    keep = np.ones(len(z), bool)
    for _ in range(2):  # once more without blocks across an edge (another surface)
        coef, *_ = np.linalg.lstsq(design[keep], z[keep], rcond=None)
        residual = z - design @ coef
        spread = 1.4826 * float(np.median(np.abs(residual[keep])))
        if spread > 0:
            keep = np.abs(residual) <= 3 * spread
        if keep.sum() < MIN_BLOCKS:
            return math.nan
    dof = int(keep.sum()) - design.shape[1]
    scatter = math.sqrt(float(np.sum(residual[keep] ** 2)) / dof)
    return SCATTER_GAIN * scatter / float(np.median(z))


def compare_target(
    session: Session, target: Target, depth: np.ndarray, sigma: np.ndarray, run_id: str,
    lens: Lens,
    offset: tuple[float, float] = (0.0, math.nan),
) -> Comparison:
    """The laser range of ``target`` against the depth map's range at its pixel.

    ``depth``, ``sigma``: (H, W) float32, metres, z in the left camera. The estimate is
    the median z over the target's window, turned into the range along the centre
    pixel's ray from the laser's aperture (rig profile's rangefinder offset) by
    :func:`rigkit.rangefinder.ranging.range_on_ray`, the ray back-projected through
    ``lens``, the run's (:func:`rigkit.export.runinfo.run_info`, as ``rigkit export``
    back-projects every point). The laser range is the median of the target's
    readings, so one typo among good shots does not move it.

    The estimate's one-sigma is its own, measured (:func:`median_scatter`; no better
    than the per-pixel sigma over the square root of the window's pixels; the per-pixel
    sigma where nothing measures it), with the run's offset share added: ``offset`` is
    (the offset's one-sigma share of depth at the run's median depth, that depth in m),
    as :class:`rigkit.pipeline.estimate.DepthResult` gives them.
    """
    profile = session.rig()
    height, width = depth.shape
    half = target.window_px // 2
    u, v = target.pixel
    cu, cv = round(u), round(v)
    rows = slice(max(cv - half, 0), min(cv + half + 1, height))
    cols = slice(max(cu - half, 0), min(cu + half + 1, width))
    window, window_sigma = depth[rows, cols], sigma[rows, cols]
    finite = np.isfinite(window)
    laser = np.array([r.slope_distance_m for r in target.readings], float)
    laser_range = float(np.median(laser)) if laser.size else math.nan  # robust to a typo
    estimate = sigma_range = math.nan
    if finite.any():
        z = float(np.median(window[finite]))
        z_sigma = float(np.median(window_sigma[finite]))
        ray = lens.rays(np.array([[u, v]], np.float64))[0]
        estimate = range_on_ray(z, (ray[0], ray[1], ray[2]), aperture_offset(profile))
        sigma_range = _estimate_sigma(depth, target, z_sigma / z, int(finite.sum()),
                                      offset, z) * estimate
    status = STATUS_OK if finite.any() and laser.size else (
        STATUS_NO_READING if not laser.size else STATUS_NO_ESTIMATE
    )
    error = estimate - laser_range
    return Comparison(
        run_id=run_id,
        time_utc=utc_now(),
        session=session.name,
        target=target.name,
        u=float(u),
        v=float(v),
        window_px=target.window_px,
        laser_range_m=laser_range,
        laser_readings=int(laser.size),
        laser_spread_m=float(laser.std()) if laser.size else math.nan,
        estimate_range_m=estimate,
        estimate_sigma_m=sigma_range,
        valid_fraction=float(finite.mean()),
        error_m=error,
        error_pct=100 * error / laser_range if laser.size else math.nan,
        status=status,
    )


def _estimate_sigma(depth: np.ndarray, target: Target, pixel_sigma: float, pixels: int,
                    offset: tuple[float, float], z: float) -> float:
    """A target's relative one-sigma: its median's own, measured (never below the
    per-pixel sigma over the square root of its ``pixels``), and the offset's share at
    its depth ``z``; ``pixel_sigma`` (relative) where nothing measures it."""
    measured = median_scatter(depth, target.pixel[0], target.pixel[1], target.window_px)
    if not math.isfinite(measured):
        return pixel_sigma
    fraction, median_depth = offset
    share = fraction * z / median_depth if fraction > 0 and median_depth > 0 else 0.0
    return math.hypot(max(measured, 1.2533 * pixel_sigma / math.sqrt(pixels)), share)
