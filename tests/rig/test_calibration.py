"""rigkit.rig.calibration: the rig's scale from laser targets, on targets made from the
model with a known C_lb factor k and f*C_lr factor a (1/e = a/t + (k - a)/z0), adjusted
with the profile's tolerances as rows, blunders found by their standardised residuals."""

from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from rigkit.errors import InputError
from rigkit.rig import load_rig
from rigkit.rig.adjustment import LaserTarget
from rigkit.rig.calibrated import calibrated_name, calibrated_profile
from rigkit.rig.calibration import fit_scale
from rigkit.rig.defaults import CRITICAL_W
from rigkit.rig.profile import dump_rig
from rigkit.rig.provenance import Calibration, CalibrationSource

ROOT = Path(__file__).resolve().parents[2]
LASER_M = 0.3  # one reading's sigma
OWN = 0.002  # the estimate's own relative sigma
WIDE = np.array([180.0, 230.0, 280.0, 340.0, 420.0, 500.0])


@pytest.fixture(scope="module")
def profile():
    return load_rig(ROOT / "rigs" / "p1000-tripod.yaml")  # 1 % on f, 2 cm on each baseline


def _targets(k: float, a: float = 1.0, ranges=None, z0: float = 300.0, seed: int = 0,
             run: str = "s1", offset: float = 0.0, own: float = OWN,
             laser_sigma: float = LASER_M) -> list[LaserTarget]:
    """Targets whose estimates follow the model with factors ``k``, ``a``, with noise,
    each on its own pixel (200 px apart, windows of 9 px)."""
    rng = np.random.default_rng(seed)
    ranges = ranges if ranges is not None else np.linspace(285.0, 315.0, 6)
    out = []
    for i, t in enumerate(ranges):
        e = 1 / (a / t + (k - a) / z0)
        laser = t + rng.normal(0, laser_sigma)
        estimate = e * (1 + rng.normal(0, own))
        out.append(LaserTarget(f"{run}/T{i + 1}", laser, laser_sigma, estimate, own * estimate,
                               z0, run, offset, (200.0 * (i + 1), 500.0), 9))
    return out


def _short(targets: list[LaserTarget], index: int, factor: float) -> None:
    """The reading of target ``index`` ``factor`` of the truth (a laser on something
    nearer)."""
    targets[index] = replace(targets[index], laser_m=targets[index].laser_m * factor)


def test_a_scale_error_is_recovered_within_its_sigma(profile) -> None:
    zs = []
    for seed in range(40):
        fit = fit_scale(_targets(1.015, seed=seed), profile)
        zs.append((fit.scale - 1.015) / fit.scale_sigma)
        assert not fit.shape_fitted and fit.shape == 1.0  # 285-315 m: no depth to see it
    zs = np.array(zs)
    assert np.mean(np.abs(zs) <= 2) >= 0.9  # honest sigma: ~95 % within 2 sigma
    assert 0.5 < np.sqrt(np.mean(zs**2)) < 1.6


# ------------------------------------------------------------ the priors are rows


def test_one_target_against_the_tape_has_a_degree_of_freedom(profile) -> None:
    """The tape's C_lb is a row of the fit and its test: one target is weighed against it
    (on 81dfff3 one target had no degrees of freedom and nothing tested it)."""
    fit = fit_scale(_targets(1.003, seed=1)[:1], profile)
    assert fit.dof == 1 and math.isfinite(fit.chance) and not fit.checked
    assert [r.name for r in fit.residuals] == ["s1/T1", "C_lb", "laser c"]


def test_one_target_lasered_far_short_is_refused_naming_it(profile) -> None:
    """A target lasered at 30 m against ~302 m: neither it nor the tape supports a
    compromise C_lb; one target cannot tell which is wrong (on 81dfff3: C_lb 1.828 m
    written, exit 0)."""
    targets = _targets(1.0, seed=2, ranges=np.array([302.0]))
    _short(targets, 0, 0.1)
    with pytest.raises(InputError, match=r"s1/T1 and the tape's C_lb.* disagree.*cannot tell"):
        fit_scale(targets, profile)
    with pytest.raises(InputError, match=r"imply C_lb = -?\d+\.\d+ m.*measured something else"):
        fit_scale(targets, profile, overrule=True)  # the lasers alone: no rig


def test_two_targets_a_tenth_short_are_refused(profile) -> None:
    """Two readings a tenth of the truth (on 81dfff3: f halved, C_lr 0.99 m, exit 0)."""
    targets = _targets(1.0, seed=3, ranges=np.array([250.0, 350.0]))
    _short(targets, 0, 0.1)
    _short(targets, 1, 0.1)
    with pytest.raises(InputError, match=r"s1/T1.*s1/T2|s1/T2.*s1/T1|the lasers \(s1/T1, s1/T2\)"):
        fit_scale(targets, profile)


def test_a_c_lb_beyond_the_tape_is_refused_unless_overruled(profile) -> None:
    """The lasers put C_lb 4 % from a tape that claims 1 %: refused naming them, or, with
    the user's word, the tape overruled and said."""
    targets = _targets(1.04, seed=4)
    with pytest.raises(InputError, match=r"the lasers \(s1/T1, .*s1/T6\) put C_lb at "
                                         r"2\.0[78]\d\d.*beyond-tolerance"):
        fit_scale(targets, profile)
    fit = fit_scale(targets, profile, overrule=True)
    assert [name for name, _ in fit.overruled] == ["C_lb"]
    assert fit.scale == pytest.approx(1.04, abs=3 * fit.map_scale_sigma)
    assert "C_lb" not in [r.name for r in fit.residuals]


# ------------------------------------------------------------ blunders


def test_a_blunder_beyond_3_3_sigma_is_left_out(profile) -> None:
    """A reading 1.1 % off at ~0.22 % sigma (~5 sigma, under 81dfff3's 5-sigma cut once
    its own leave-one-out spread is counted) is a blunder at Baarda's 3.29."""
    targets = _targets(1.015, seed=5)
    _short(targets, 2, 1.011)
    fit = fit_scale(targets, profile)
    assert [r.target.name for r in fit.rejected] == ["s1/T3"]
    assert fit.rejected[0].w > CRITICAL_W
    assert fit.rejected[0].miss_pct == pytest.approx(-1.1, abs=0.4)  # its estimate short
    clean = fit_scale([t for i, t in enumerate(targets) if i != 2], profile)
    assert fit.scale == pytest.approx(clean.scale, abs=1e-12)


def test_two_gross_errors_among_seven_are_both_left_out(profile) -> None:
    """0-2 gross errors (laser 5-90 % short): each named, the fit as without them (on
    81dfff3 at most a quarter could be left out, so two of seven stopped it)."""
    targets = _targets(1.01, seed=6, ranges=np.linspace(285.0, 315.0, 7))
    _short(targets, 1, 0.95)
    _short(targets, 4, 0.3)
    fit = fit_scale(targets, profile)
    assert sorted(r.target.name for r in fit.rejected) == ["s1/T2", "s1/T5"]
    assert fit.scale == pytest.approx(1.01, abs=3 * fit.map_scale_sigma)


def test_more_blunders_than_good_targets_are_refused_naming_them(profile) -> None:
    targets = _targets(1.0, seed=7, ranges=np.array([290.0, 300.0, 310.0]))
    _short(targets, 0, 0.5)
    _short(targets, 2, 0.8)
    with pytest.raises(InputError, match=r"s1/T[13], s1/T[13] disagree with the other "
                                         r"targets.*no more can be left out"):
        fit_scale(targets, profile)


def test_many_moderate_disagreements_stop_the_fit(profile) -> None:
    """Targets scattering far beyond their sigma with no single blunder: refused."""
    targets = _targets(1.0, seed=8, ranges=np.linspace(285.0, 315.0, 12))
    targets = [replace(t, estimate_m=t.estimate_m * (1 + 0.006 * (-1) ** i))
               for i, t in enumerate(targets)]
    with pytest.raises(InputError, match="disagree beyond their sigmas|no more can be"):
        fit_scale(targets, profile)


# ------------------------------------------------------------ independence


def test_copies_of_one_target_count_once(profile) -> None:
    """Six names on one pixel with one reading (on 81dfff3: "checked: 6/6")."""
    one = _targets(1.0, seed=9)[0]
    copies = [replace(one, name=f"s1/T{i + 1}") for i in range(6)]
    fit = fit_scale(copies, profile)
    assert [t.name for t in fit.used] == ["s1/T1"]
    assert [c.name for c in fit.duplicates[0][1]] == [f"s1/T{i}" for i in range(2, 7)]
    assert not fit.checked and fit.checks == ()


def test_leave_one_out_leaves_the_twins_out(profile) -> None:
    """Two targets whose windows overlap share their depth error (+0.6 %): each one's
    check is made without the other, so it shows (on 81dfff3 the twin stayed in)."""
    targets = _targets(1.0, seed=10, ranges=np.linspace(285.0, 315.0, 5))
    first = replace(targets[0], estimate_m=targets[0].estimate_m * 1.006)
    twin = replace(first, name="s1/T1b", laser_m=first.laser_m + 0.2,
                   pixel=(first.pixel[0] + 4, first.pixel[1]))
    fit = fit_scale([first, twin, *targets[1:]], profile)
    check = next(c for c in fit.checks if c.target.name == "s1/T1")
    assert check.miss_pct == pytest.approx(0.6, abs=0.2)
    assert all(abs(c.miss_pct) < 0.45 for c in fit.checks[2:])


def test_held_out_targets_only_check_the_fit(profile) -> None:
    targets = _targets(1.012, seed=11, ranges=np.linspace(285.0, 315.0, 8))
    held = [targets[1], replace(targets[5], laser_m=targets[5].laser_m * 0.97)]
    used = [t for i, t in enumerate(targets) if i not in (1, 5)]
    fit = fit_scale(used, profile, held_out=held)
    alone = fit_scale(used, profile)
    assert fit.scale == alone.scale and not fit.rejected
    assert [c.target.name for c in fit.held_out] == ["s1/T2", "s1/T6"]
    assert fit.held_out[0].within and abs(fit.held_out[0].miss_pct) < 0.6
    assert fit.held_out[1].miss_pct == pytest.approx(3.0, abs=0.6) and not fit.held_out[1].within


# ------------------------------------------------------------ f * C_lr, one rig, the laser


def test_f_c_lr_is_fitted_where_the_targets_alone_determine_it(profile) -> None:
    """Targets that fix a better than the lens spec does decide it, even where they do
    not halve its sigma (81dfff3 fitted it only below half the prior's)."""
    ranges = np.linspace(275.0, 325.0, 6)
    fit = fit_scale(_targets(1.0, a=1.008, ranges=ranges, seed=12, own=0.001), profile)
    prior = math.hypot(0.01, 0.01)
    assert 0.6 * prior < fit.shape_targets_sigma < prior
    assert fit.shape_fitted and fit.shape_sigma < fit.shape_targets_sigma


def test_a_shape_error_is_fitted_where_the_targets_span_depth(profile) -> None:
    fit = fit_scale(_targets(0.99, a=1.012, ranges=WIDE, seed=4), profile)
    assert fit.shape_fitted
    assert fit.shape == pytest.approx(1.012, abs=3 * fit.shape_sigma)
    assert fit.scale == pytest.approx(0.99, abs=3 * fit.map_scale_sigma)


def test_a_focal_length_beyond_its_tolerance_is_refused_unless_overruled(profile) -> None:
    targets = _targets(0.99, a=1.05, ranges=WIDE, seed=4)
    with pytest.raises(InputError, match=r"put f\*C_lr at x 1\.0\d+.*--beyond-tolerance"):
        fit_scale(targets, profile)
    fit = fit_scale(targets, profile, overrule=True)
    assert fit.shape_fitted and fit.shape == pytest.approx(1.05, abs=3 * fit.shape_sigma)


def test_two_rigs_under_one_profile_are_refused(profile) -> None:
    """Two sessions 0.6 % apart in scale, each known to 0.1 %: not one rig (on 81dfff3
    merged without a word)."""
    runs = _targets(1.0, seed=13, run="a") + _targets(1.006, seed=14, run="b")
    with pytest.raises(InputError, match="do not share one scale"):
        fit_scale(runs, profile)
    same = _targets(1.0, seed=15, run="a") + _targets(1.0, seed=16, run="b")
    fit = fit_scale(same, profile)
    assert len(fit.runs) == 2 and fit.one_rig_chance > 1e-3


def test_a_runs_offset_error_widens_c_lb_but_not_the_maps_scale(profile) -> None:
    one = fit_scale(_targets(1.0, seed=9, offset=0.004), profile)
    assert one.scale_sigma == pytest.approx(math.hypot(one.map_scale_sigma, 0.004))
    runs = _targets(1.0, seed=10, run="a", offset=0.004) + _targets(
        1.0, seed=11, run="b", offset=0.004, z0=250.0, ranges=np.linspace(240, 260, 6))
    both = fit_scale(runs, profile)
    assert both.scale_sigma == pytest.approx(math.hypot(both.map_scale_sigma,
                                                        0.004 / math.sqrt(2)))


def test_the_lasers_constant_is_found_where_the_targets_allow(profile) -> None:
    """Readings 2 m long from a laser good to 5 cm over 40-600 m: the targets fix the
    constant; over 285-315 m they cannot, and it is assumed."""
    spread = np.geomspace(40.0, 600.0, 16)
    targets = [replace(t, laser_m=t.laser_m + 2.0) for t in _targets(
        1.0, ranges=spread, seed=17, own=0.0002, laser_sigma=0.05)]
    with pytest.raises(InputError, match=r"the laser's additive constant at \+2\.\d\d"):
        fit_scale(targets, profile)
    fit = fit_scale(targets, profile, overrule=True)
    assert fit.laser_constant_seen and [name for name, _ in fit.overruled] == ["laser c"]
    assert fit.laser_constant_m[0] == pytest.approx(2.0, abs=3 * fit.laser_constant_m[1])
    narrow = fit_scale(_targets(1.0, seed=18), profile)
    assert not narrow.laser_constant_seen
    assert narrow.laser_constant_m[1] == pytest.approx(LASER_M, rel=0.2)  # its prior's


def test_nothing_usable_is_one_line(profile) -> None:
    bad = [replace(t, estimate_m=math.nan) for t in _targets(1.0)]
    with pytest.raises(InputError, match="no laser target"):
        fit_scale(bad, profile)


# ------------------------------------------------------------ the profile it gives


def _record() -> Calibration:
    source = CalibrationSource("ridge-0412", "/data/ridge-0412", "ab" * 32,
                               "20261128T080000Z-0001", "2026:11:27 10:15:00",
                               {"T1": (200.0, 500.0)})
    return Calibration("2026-11-28T09:00:00Z", "p1000-tripod", (source,), 300.0)


def test_the_profile_carries_the_fit_its_provenance_and_reads_back(profile,
                                                                    tmp_path: Path) -> None:
    fit = fit_scale(_targets(0.99, a=1.012, ranges=WIDE, seed=3), profile)
    out = calibrated_profile(profile, fit, _record())
    path = tmp_path / "cal.yaml"
    path.write_text(dump_rig(out.profile))
    back = load_rig(path)
    assert back.name == "p1000-tripod-laser-calibrated-20261128"
    assert back.baseline_lb.value_m == pytest.approx(2.0 * fit.scale)
    assert back.baseline_lb.tolerance_m == pytest.approx(2.0 * fit.scale_sigma)
    # f*C_lr moved by the fitted factor, shared by the tolerances (1 % on f, 1 % on C_lr).
    product = back.focal_px * back.baseline_lr.value_m
    assert product == pytest.approx(profile.focal_px * 2.0 * fit.shape)
    assert back.focal_px / profile.focal_px == pytest.approx(math.sqrt(fit.shape))
    assert math.hypot(back.focal_tolerance, back.baseline_lr.relative_tolerance) == (
        pytest.approx(fit.shape_sigma))
    record = back.calibration
    assert record is not None and record.sessions[0].used == {"T1": (200.0, 500.0)}
    assert [line.split()[0] for line in record.changes] == ["C_lb", "f", "C_lr"]
    assert record.source("ab" * 32) is not None and record.source("cd" * 32) is None


def test_a_calibration_worse_than_the_tape_keeps_the_tape(profile) -> None:
    """A run whose offset leaves C_lb known to 1.5 % for other captures: the tape's 1 %
    stays, and says why."""
    fit = fit_scale(_targets(1.0, seed=19, offset=0.015), profile)
    out = calibrated_profile(profile, fit, _record())
    assert out.profile.baseline_lb == profile.baseline_lb
    assert out.changes == () and "no better than the tape" in out.kept[0]


@pytest.mark.parametrize(("name", "expected"), [
    ("ridge-taped", "ridge-laser-calibrated-20261128"),
    ("ridge", "ridge-laser-calibrated-20261128"),
    ("ridge-laser-calibrated-20261001", "ridge-laser-calibrated-20261128"),
])
def test_a_calibrated_profile_is_named_so(name: str, expected: str) -> None:
    assert calibrated_name(name, "2026-11-28T09:00:00Z") == expected
