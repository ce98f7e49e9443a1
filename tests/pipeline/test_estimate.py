"""What the orchestrator says of the offset's share of depth error: its warning and the
advice in it. (Whether its standard errors cover the truth: test_coverage.py.)"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from rigkit.pipeline.estimate import OFFSET_WARNING_FRACTION


def test_no_depth_has_no_sigma(result) -> None:
    assert np.isnan(result.sigma[~np.isfinite(result.depth)]).all()
    assert np.isfinite(result.sigma[np.isfinite(result.depth)]).all()


def test_the_offset_warning_says_its_share_of_depth(result) -> None:
    assert result.median_depth_m == float(np.nanmedian(result.depth))
    assert result.diagnostics()["offset_depth_error_fraction"] == result.offset_depth_fraction
    steady = replace(result, offset_depth_fraction=0.9 * OFFSET_WARNING_FRACTION)
    assert steady.offset_warning() is None
    shaky = replace(result, offset_depth_fraction=0.0042)
    assert "+-0.42 % of depth" in str(shaky.offset_warning())


def test_the_offset_warning_names_its_largest_part(result) -> None:
    # The parts add in quadrature to the offset's standard error, and the advice is
    # the one for the largest: bursts do nothing for a lens or principal points.
    parts = result.offset_sources()
    total = result.ambiguity.offset_sigma_px
    assert np.sqrt(sum(v**2 for v in parts.values())) == pytest.approx(total, rel=1e-6)
    amb = result.ambiguity
    for sigmas, says in (((3.0, 0.1), "bursts of several frames"),
                         ((3.0, 2.9), "one camera moved between"),
                         ((0.5, 0.1), "bursts of several frames")):
        total, pp = sigmas
        shaky = replace(result, offset_depth_fraction=0.01, lens_fit=None,
                        ambiguity=replace(amb, offset_sigma_px=total,
                                          principal_point_sigma_px=pp))
        assert says in str(shaky.offset_warning())
    lens_fit = replace(result.lens_fit, offset_sigma_px=2.5)
    blurred = replace(result, offset_depth_fraction=0.01, lens_fit=lens_fit,
                      ambiguity=replace(amb, offset_sigma_px=3.0, principal_point_sigma_px=0.2))
    assert "give the lens in the rig profile" in str(blurred.offset_warning())


def test_the_air_advice_says_how_many_frames_would_do(result) -> None:
    # 3.0 px of offset sigma, 0.1 of it from principal points, leave 1 % of depth: the
    # air's 2.998 px must fall to sqrt(0.9^2 - 0.1^2) px for 0.3 %, so by sqrt(12.0).
    amb = replace(result.ambiguity, offset_sigma_px=3.0, principal_point_sigma_px=0.1)
    shaky = replace(result, offset_depth_fraction=0.01, lens_fit=None, ambiguity=amb)
    assert "about 12 frames per position would bring it to 0.3 %" in str(shaky.offset_warning())
    assert "about 57 frames per position" in str(shaky.offset_warning(frames=5))
    # Where the principal points alone leave more than 0.3 %, no number of frames will.
    stuck = replace(shaky, ambiguity=replace(amb, principal_point_sigma_px=1.0))
    assert "would bring it" not in str(stuck.offset_warning())
