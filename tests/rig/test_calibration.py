"""rigkit.rig.calibration: the rig's scale from laser targets, on targets made from the
model with a known C_lb factor k and f*C_lr factor a (1/e = a/t + (k - a)/z0)."""

from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from rigkit.errors import InputError
from rigkit.rig import load_rig
from rigkit.rig.calibration import (
    LaserTarget,
    calibrated_profile,
    fit_scale,
)
from rigkit.rig.profile import dump_rig

ROOT = Path(__file__).resolve().parents[2]
LASER_M = 0.3  # one reading's sigma
OWN = 0.002  # the estimate's own relative sigma


@pytest.fixture(scope="module")
def profile():
    return load_rig(ROOT / "rigs" / "p1000-tripod.yaml")  # 1 % on f, 2 cm on each baseline


def _targets(k: float, a: float = 1.0, ranges=None, z0: float = 300.0, seed: int = 0,
             run: str = "s1", offset: float = 0.0) -> list[LaserTarget]:
    """Targets whose estimates follow the model with factors ``k``, ``a``, with noise."""
    rng = np.random.default_rng(seed)
    ranges = ranges if ranges is not None else np.linspace(285.0, 315.0, 6)
    out = []
    for i, t in enumerate(ranges):
        e = 1 / (a / t + (k - a) / z0)
        laser = t + rng.normal(0, LASER_M)
        estimate = e * (1 + rng.normal(0, OWN))
        out.append(LaserTarget(f"{run}/T{i + 1}", laser, LASER_M, estimate, OWN * estimate,
                               z0, run, offset))
    return out


def test_a_scale_error_is_recovered_within_its_sigma(profile) -> None:
    zs = []
    for seed in range(40):
        fit = fit_scale(_targets(1.015, seed=seed), profile)
        zs.append((fit.scale - 1.015) / fit.scale_sigma)
        assert not fit.shape_fitted and fit.shape == 1.0  # 285-315 m: no depth to see it
    zs = np.array(zs)
    assert np.mean(np.abs(zs) <= 2) >= 0.9  # honest sigma: ~95 % within 2 sigma
    assert 0.5 < np.sqrt(np.mean(zs**2)) < 1.6


def test_a_shape_error_is_fitted_where_the_targets_span_depth(profile) -> None:
    wide = np.array([180.0, 230.0, 280.0, 340.0, 420.0, 500.0])
    fit = fit_scale(_targets(0.99, a=1.05, ranges=wide, seed=3), profile)
    assert fit.shape_fitted
    assert fit.shape == pytest.approx(1.05, abs=3 * fit.shape_sigma)
    assert fit.scale == pytest.approx(0.99, abs=3 * fit.map_scale_sigma)


def test_a_stray_reading_is_named_and_left_out(profile) -> None:
    targets = _targets(1.015, seed=5)
    targets[2] = replace(targets[2], laser_m=targets[2].laser_m * 1.10)  # 10 % off
    fit = fit_scale(targets, profile)
    assert [t.name for t, _ in fit.strays] == ["s1/T3"]
    assert fit.strays[0][1] == pytest.approx(-10.0, abs=1.0)  # its estimate reads 10 % short
    clean = fit_scale([t for i, t in enumerate(targets) if i != 2], profile)
    assert fit.scale == pytest.approx(clean.scale, abs=1e-12)


def test_targets_that_disagree_stop_the_fit_naming_one(profile) -> None:
    targets = _targets(1.0, seed=6)
    for i in (1, 4):  # two of six off by 3 %: more than one stray in six
        targets[i] = replace(targets[i], laser_m=targets[i].laser_m * 1.03)
    with pytest.raises(InputError, match=r"disagree.*s1/T[25] misses"):
        fit_scale(targets, profile)


def test_each_check_leaves_its_own_target_out(profile) -> None:
    targets = _targets(1.0, seed=7)
    targets[0] = replace(targets[0], estimate_m=targets[0].estimate_m * 1.006)  # 3 sigma
    fit = fit_scale(targets, profile)
    assert not fit.strays and fit.checked and len(fit.checks) == 6
    first = fit.checks[0]
    assert first.target is targets[0]
    # Against the fit without it, its miss is its own +0.6 %, not shared with the others.
    assert first.miss_pct == pytest.approx(0.6, abs=0.25)
    assert first.sigma_pct > 0
    assert all(abs(c.miss_pct) < 0.4 for c in fit.checks[1:])


def test_fewer_than_three_targets_calibrate_but_do_not_check(profile) -> None:
    fit = fit_scale(_targets(1.01, seed=8)[:2], profile)
    assert not fit.checked and fit.checks == ()
    assert fit.scale == pytest.approx(1.01, abs=3 * fit.scale_sigma)


def test_a_runs_offset_error_widens_c_lb_but_not_the_maps_scale(profile) -> None:
    one = fit_scale(_targets(1.0, seed=9, offset=0.004), profile)
    assert one.scale_sigma == pytest.approx(math.hypot(one.map_scale_sigma, 0.004))
    runs = _targets(1.0, seed=10, run="a", offset=0.004) + _targets(
        1.0, seed=11, run="b", offset=0.004, z0=250.0, ranges=np.linspace(240, 260, 6))
    both = fit_scale(runs, profile)
    assert both.scale_sigma == pytest.approx(math.hypot(both.map_scale_sigma,
                                                        0.004 / math.sqrt(2)))


def test_nothing_usable_is_one_line(profile) -> None:
    bad = [replace(t, estimate_m=math.nan) for t in _targets(1.0)]
    with pytest.raises(InputError, match="no laser target"):
        fit_scale(bad, profile)


def test_the_profile_carries_the_fit_and_reads_back(profile, tmp_path: Path) -> None:
    wide = np.array([180.0, 230.0, 280.0, 340.0, 420.0, 500.0])
    fit = fit_scale(_targets(0.99, a=1.05, ranges=wide, seed=3), profile)
    out = calibrated_profile(profile, fit, "calibrated in a test")
    path = tmp_path / "cal.yaml"
    path.write_text(dump_rig(out))
    back = load_rig(path)
    assert back.baseline_lb.value_m == pytest.approx(2.0 * fit.scale)
    assert back.baseline_lb.tolerance_m == pytest.approx(2.0 * fit.scale_sigma)
    # f*C_lr moved by the fitted factor, shared by the tolerances (1 % on f, 1 % on C_lr).
    product = back.focal_px * back.baseline_lr.value_m
    assert product == pytest.approx(profile.focal_px * 2.0 * fit.shape)
    assert back.focal_px / profile.focal_px == pytest.approx(math.sqrt(fit.shape))
    assert math.hypot(back.focal_tolerance, back.baseline_lr.relative_tolerance) == (
        pytest.approx(fit.shape_sigma))
    assert "calibrated in a test" in back.notes
