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
from rigkit.rangefinder.ranging import profile_range_from_depth


def compare_target(
    session: Session, target: Target, depth: np.ndarray, sigma: np.ndarray, run_id: str
) -> Comparison:
    """The laser range of ``target`` against the depth map's range at its pixel.

    ``depth``, ``sigma``: (H, W) float32, metres, z in the left camera. The estimate is
    the median z over the target's window, turned into the range along the centre
    pixel's ray from the laser's aperture (rig profile's rangefinder offset) by
    :func:`rigkit.rangefinder.ranging.range_from_depth`. The laser range is the median
    of the target's readings, so one typo among good shots does not move it.
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
        estimate = profile_range_from_depth(profile, (width, height), z, (u, v))
        sigma_range = z_sigma * estimate / z
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
