"""What an export knows of the run that made a depth map: its record
(:class:`rigkit.capture.results.RunRecord`, a session's ``results/depth.json`` or
``rigkit depth``'s ``D.json``, read by :func:`rigkit.capture.results.read_record`, the
one reader, which refuses a record rigkit would not have written), and the lens the
depth map lies on, through which every pixel is back-projected (the points of
``rigkit export`` and the laser comparison of ``rigkit process`` alike).

The lens is the run's left view (:attr:`rigkit.capture.results.RunRecord.left_lens`):
its distortion terms (the lens the depth went through: fitted from the views where the
run fitted one, else the rig profile's), the centre of that distortion (the fitted left
centre, else the rig's left principal point) and the focal length.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from rigkit.capture.results import RunRecord
from rigkit.pipeline.lens import Lens

FITTED = "fitted from the three views by the run"
"""Where the lens comes from when the run fitted it (``distortion_terms`` above 0)."""
PROFILE = "the rig profile's"
"""Where it comes from when the run took the profile's as given."""


@dataclass(frozen=True)
class RunInfo:
    """A depth map's run: its ``record``; ``lens``, the left view's lens (W, H the depth
    map's size; :attr:`RunRecord.left_lens`), and ``lens_source``, where it comes from
    in words."""

    record: RunRecord
    lens: Lens
    lens_source: str

    @classmethod
    def of(cls, record: RunRecord) -> RunInfo:
        """The run of a depth map from its record."""
        lens = record.left_lens
        source = FITTED if record.settings.distortion_terms else PROFILE
        if not any(lens.distortion):
            source += ", without distortion"
        return cls(record, lens, source)

    @property
    def rig(self) -> str:
        """The rig profile's name."""
        return self.record.rig_name

    @property
    def run_id(self) -> str | None:
        """The processing run's id (None for ``rigkit depth``'s files)."""
        return self.record.run_id

    @property
    def offset_depth_fraction(self) -> float | None:
        """The relative depth error the disparity offset alone leaves (one sigma, common
        to every pixel at a depth; None: not known)."""
        return self.record.offset_depth_fraction

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready, for the export's metadata."""
        record, lens = self.record, self.lens
        rig = record.rig
        return {
            "run_id": record.run_id, "time_utc": record.time_utc,
            "rigkit_version": record.rigkit_version, "rig": record.rig_name,
            "rig_values": {"focal_px": rig.focal_px, "baseline_lr_m": rig.baseline_lr_m,
                           "baseline_lb_m": rig.baseline_lb_m, "one_camera": rig.one_camera},
            "lens": {"focal_px": lens.focal_px, "size_px": list(lens.size),
                     "distortion_k1_k2_p1_p2_k3": list(lens.distortion),
                     "centre_shift_px": list(lens.shift), "source": self.lens_source},
            "settings": record.settings.as_dict(),
            "warnings": list(record.warnings),
            "offset_depth_error_fraction": record.offset_depth_fraction,
        }
