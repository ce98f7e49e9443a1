"""What the rig's error budget, its profiles, its calibration and ``rigkit rig --help``
share: the disparity error the budget assumes, the default heat shimmer, the longest
range, a laser reading's sigma and the blunders' critical value. One
place for both, in a module that loads nothing heavy (the pipeline's settings are plain
numbers), so that building the command line's parser does not load the pipeline."""

from __future__ import annotations

from rigkit.pipeline.settings import PipelineSettings

DISPARITY_ERROR_PX = PipelineSettings().stereo_noise_px
"""Default disparity (matching) error, pixels: the pipeline's own figure."""
SHIMMER_PX = 0.3
"""Default heat shimmer, px RMS per frame: moderate turbulence over 300 m at ~19 urad
per pixel (docs/field.md)."""
LASER_ACCURACY_M = 0.3
"""One laser reading's one-sigma error, m, where nothing better is known: a handheld
rangefinder's stated accuracy on a good target (a TruPulse's +-0.3 m)."""
CRITICAL_W = 3.29
"""A standardised residual beyond this marks a blunder (two-sided alpha 0.001, Baarda's
usual critical value for data snooping; :mod:`rigkit.rig.blunders`)."""
MAX_RANGE_M = 100_000.0
"""The longest range a profile (``nominal_range_m``, a rangefinder's ``max_range_m``) or
``rigkit rig check --range`` takes, m."""
