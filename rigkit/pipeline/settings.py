"""The pipeline's settings as one named, frozen record.

Every number that changes what the pipeline produces lives here, with its unit, so that
a depth map's ``depth.json`` records exactly what made it and a rig profile can
override any of them (``pipeline:`` section, docs/rig-profiles.md).
"""

from __future__ import annotations

from dataclasses import dataclass, fields
from typing import Any


@dataclass(frozen=True)
class PipelineSettings:
    """Settings of :func:`rigkit.pipeline.estimate_depth`, by stage.

    Matching: ``coarse_side_px`` side of the images SIFT runs on; ``n_points`` corners
    tracked at full resolution; ``fb_max_px`` forward-backward disagreement above which
    a track is dropped. Lens: ``distortion_terms`` radial distortion terms fitted from
    the three views (1: k1, 2: k1 and k2), starting from the given distortion; 0 uses
    the given distortion as it is. Rectification: ``disparity_margin_px`` added on both sides of
    the matched disparity range. Stereo: ``stereo_scale`` resolution of dense matching
    relative to the input (0.5 = half, as in the paper); ``fill_max_gap_px`` widest
    occlusion hole (stereo px) filled from its background neighbour, 0 = none;
    ``min_texture`` the local contrast, in units of the image noise, below which a
    pixel has no surface to match (sky, blank walls, clipped highlights); ``texture_window_px``
    the window (stereo px) that contrast is measured over. Ambiguity removal:
    ``edge_window_px`` matches this close (stereo px) to a depth edge are not used;
    ``jackknife_blocks`` spatial blocks per image side for the standard errors of the
    offset (a block jackknife) and of the fitted lens (cluster-robust), which heat
    shimmer's patch-wise errors would otherwise make too small;
    ``principal_point_sigma`` how far (one standard deviation, as a fraction of the
    image width) each view's principal point may sit from the rig's
    (:attr:`~rigkit.pipeline.rig.RigGeometry.principal_points_px`: the profile's, else
    the image centre): the prior under which the lens stage fits each view's principal
    point (one camera's: one, shared) from the three views and takes it out
    (:mod:`rigkit.pipeline.distortion`); for three cameras its spread is also added to
    the standard errors of the offset and of the fitted lens (0: every principal point
    where the rig puts it, nothing fitted and nothing added).
    Views that disagree: ``min_agreement`` the zero-mean normalised cross-correlation
    over ``agreement_window_px`` (stereo px) below which the right or the back view
    contradicts a depth (something moved between the captures): that pixel and
    ``agreement_margin_px`` around it get no depth (1 would refuse nearly all, 0 only
    a view that shows the negative; :mod:`rigkit.pipeline.agreement`).
    Uncertainty: ``stereo_noise_px`` and ``filled_noise_px`` the disparity error (px at
    the stereo resolution) of a matched and of a filled pixel.
    """

    coarse_side_px: int = 1024
    n_points: int = 3000
    fb_max_px: float = 0.1
    distortion_terms: int = 1
    disparity_margin_px: int = 24
    stereo_scale: float = 0.5
    fill_max_gap_px: int = 64
    min_texture: float = 3.0
    texture_window_px: int = 9
    edge_window_px: int = 7
    min_agreement: float = 0.5
    agreement_window_px: int = 9
    agreement_margin_px: int = 2
    jackknife_blocks: int = 4
    principal_point_sigma: float = 0.005
    stereo_noise_px: float = 0.25
    filled_noise_px: float = 2.0

    def __post_init__(self) -> None:
        for f in fields(self):
            value = getattr(self, f.name)
            if isinstance(value, bool) or not isinstance(value, int | float) or value < 0:
                raise ValueError(f"{f.name} must be a non-negative number, got {value!r}")
        if not 0 < self.stereo_scale <= 1:
            raise ValueError(f"stereo_scale must be in (0, 1], got {self.stereo_scale!r}")
        if self.min_agreement > 1:
            raise ValueError(f"min_agreement must be at most 1, got {self.min_agreement!r}")
        if self.agreement_window_px < 3:
            raise ValueError(f"agreement_window_px must be at least 3, got "
                             f"{self.agreement_window_px}")
        if self.distortion_terms > 2:
            raise ValueError(f"distortion_terms must be 0, 1 or 2, got {self.distortion_terms}")
        if self.jackknife_blocks < 2:
            raise ValueError(f"jackknife_blocks must be at least 2, got {self.jackknife_blocks}")

    def as_dict(self) -> dict[str, Any]:
        """Plain data for depth.json."""
        return {f.name: getattr(self, f.name) for f in fields(self)}


def setting_names() -> tuple[str, ...]:
    """The names a rig profile's ``pipeline:`` section may set."""
    return tuple(f.name for f in fields(PipelineSettings))


def setting_type(name: str) -> type:
    """``int`` or ``float``: what the setting ``name`` takes."""
    return int if isinstance(getattr(PipelineSettings(), name), int) else float
