"""The rig's scale from its own laser: C_lb, and f * C_lr where the targets span enough
depth to see it, fitted from laser ranges at pixels with an estimated depth, as a
surveyor adjusts a network: a-priori values with their standard deviations, every
observation a row, blunders found by their standardised residuals.

Why two numbers, and which. The pipeline's depth is z = F / (d - q) with F = f * C_lr,
d the measured disparity and q the offset the back view fixes; the back view sees the
scene magnified by z / (z + C_lb), so it pins depth in units of C_lb at the depth its
matches lie at, the run's reference depth z0 (the depth map's median stands for it).
Processed with F_p, C_lb_p where the truth is F, C_lb, a target of true range t comes out
at e with, exactly in disparity space,

    1 / e = a / t + (k - a) / z0,      a = F / F_p,   k = C_lb / C_lb_p,

so a scale error (k) moves every depth by the same factor and an error in f * C_lr (a)
stretches depth about z0. The model is linear in (a, k) whatever z0 each session has,
so the targets of many sessions of one rig are fitted together, each weighted by its
laser's accuracy and the part of its depth sigma that is its own (the window median's
measured scatter, :func:`rigkit.batch.compare.median_scatter`; the offset's share is
common to a run's targets: the fit measures it, it is not noise). A scale error and a
C_lb error are the same thing: what is called C_lb here is whatever makes the depth
map's scale right.

The adjustment. The profile's tolerances are a-priori observations a = 1 and k = 1 with
their sigmas (the tape's and the lens spec's): rows of the least squares beside the
targets' and of its global test (the chi-square of every row, degrees of freedom = rows
- unknowns), so one target is already weighed against the tape. Blunders are found by
data snooping (Baarda): each row's standardised residual w = v / (sigma sqrt(r)), r its
redundancy number, equal to its miss against the fit made without it in units of that
miss's sigma; the worst beyond :data:`CRITICAL_W` (3.29, alpha 0.001) is left out and
the adjustment repeated. A row whose w correlates with another's beyond
:data:`INSEPARABLE_RHO` cannot be told from it (one target against the tape, two targets
alone): both are named and nothing is fitted. A prior found to be the blunder means the
tape (or the lens spec) is beyond its tolerance: refused, naming the targets that say
so, unless the caller overrules the prior. At most a minority of the targets is left out.

Twins and checks. Targets on the same pixel with the same reading are one target
(counted once); targets of one run whose windows overlap share depth pixels, so each
target's leave-one-out check leaves out its twins with it. Targets held out of the fit
are checked against it; no target checks the fit it is part of.

The least squares is :mod:`rigkit.rig.adjustment`, the blunders' search
:mod:`rigkit.rig.blunders`, the profile a fit gives :mod:`rigkit.rig.calibrated`.

Ideas credited: the a-priori values as observations, the test of the variance of unit
weight and data snooping with standardised residuals are the textbook geodetic
adjustment (Baarda 1968, "A testing procedure for use in geodetic networks").
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np

from rigkit.errors import InputError
from rigkit.rig.adjustment import (
    FIXED,
    HELD,
    MIN_CHECKED,
    PRIOR_CONSTANT,
    PRIORS,
    Adjustment,
    LaserTarget,
    Model,
    adjust,
    chi2_chance,
    final_adjustment,
    observation_rows,
    prediction,
    shape_sigma_alone,
)
from rigkit.rig.blunders import Rejected, snoop
from rigkit.rig.profile import RigProfile

GLOBAL_P = 0.05
"""The global test: a chi-square with a smaller chance than this says the rows scatter
more than their sigmas (the covariance is then scaled by the variance of unit weight)."""
CONSISTENT_P = 1e-4
"""Rows whose chi-square has a smaller chance than this, with no single blunder to
blame, disagree with each other: nothing is fitted."""
ONE_RIG_P = 1e-3
"""Sessions whose scales differ with a smaller chance than this are not one rig."""
UNSTATED_TOLERANCE = 0.01
"""The relative tolerance taken for f, C_lr or C_lb where a profile states none (0): a
lens spec's ~1 %, a tape's 2 cm on 2 m."""
GOAL_PCT = 1.0
"""The agreement a check is counted against, % of the range (the field verdict's goal)."""
MIN_CONSTANT_SIGMA_M = 0.01
"""The least a-priori sigma of the laser's additive constant, m (readings stated exact
still have one to a centimetre)."""
CONSTANT_SEEN = 0.5
"""The laser's additive constant is determined by the targets (and written into the
profile's rangefinder offset) where they bring its sigma below this share of its prior's."""


@dataclass(frozen=True)
class Check:
    """A target checked by a fit it is no part of: the calibrated range (m) its estimate
    gives under that fit, the miss against the laser and its sigma, % of range (positive:
    the calibrated depth reads long)."""

    target: LaserTarget
    calibrated_m: float
    miss_pct: float
    sigma_pct: float

    @property
    def within(self) -> bool:
        return abs(self.miss_pct) <= GOAL_PCT


@dataclass(frozen=True)
class Residual:
    """A row of the final adjustment: its residual (the fit minus the observation; for a
    target its calibrated range minus its laser, % of range; for a prior the fitted
    factor minus 1, %, or for the laser's constant its value, m), its standardised
    residual ``w`` and redundancy number ``r``."""

    name: str
    residual_pct: float
    w: float
    redundancy: float
    target: LaserTarget | None = None


@dataclass(frozen=True)
class RunScale:
    """One run's own scale (C_lb's factor with the fit's f * C_lr) and its sigma, the
    run's offset share included: what the one-rig test compares. ``run``: its name (its
    targets' names before the ``/``, else its run key)."""

    run: str
    scale: float
    sigma: float
    targets: int


@dataclass(frozen=True)
class ScaleFit:
    """What the lasers say: ``scale`` = k (C_lb's factor) and ``shape`` = a (f * C_lr's),
    each with its one-sigma; ``shape_fitted`` False where a was held at 1 (the targets do
    not determine it better than the profile's tolerances do).

    ``map_scale_sigma`` is how well the fit fixes the scale of the depth maps it came
    from; ``scale_sigma`` how well C_lb is known for other captures: it adds the runs'
    offset errors, which shift all of a run's targets together and look exactly like a
    C_lb error there (several runs average them down). Both are scaled by the a-posteriori
    variance of unit weight ``sigma0**2`` where it exceeds 1.

    ``used``: the targets fitted; ``duplicates``: (kept, its copies) merged into one;
    ``rejected``: blunders left out; ``overruled``: priors the caller let the lasers
    overrule (with their w); ``residuals``: every row of the final adjustment; ``checks``:
    leave-one-out (twins left out together; empty below :data:`MIN_CHECKED` targets);
    ``held_out``: targets held out of the fit and checked against it; ``runs``: each run's
    own scale, and ``one_rig_chance`` the chance of their spread (NaN for one run);
    ``laser_constant_m``: the laser's additive constant (value, sigma, m; a reading is
    the true range plus it), a priori 0 +- ``laser_constant_prior_m``;
    ``laser_constant_seen`` where the targets determine it (it is then written into the
    profile's rangefinder offset; else it stays assumed)."""

    scale: float
    scale_sigma: float
    map_scale_sigma: float
    shape: float
    shape_sigma: float
    shape_fitted: bool
    used: tuple[LaserTarget, ...]
    checks: tuple[Check, ...]
    chi2: float
    dof: int
    chance: float
    sigma0: float
    reference_m: float
    residuals: tuple[Residual, ...] = ()
    rejected: tuple[Rejected, ...] = ()
    duplicates: tuple[tuple[LaserTarget, tuple[LaserTarget, ...]], ...] = ()
    overruled: tuple[tuple[str, float], ...] = ()
    held_out: tuple[Check, ...] = ()
    runs: tuple[RunScale, ...] = ()
    one_rig_chance: float = math.nan
    laser_constant_m: tuple[float, float] = (0.0, math.inf)
    laser_constant_prior_m: float = math.inf
    laser_constant_seen: bool = False
    shape_targets_sigma: float = math.inf

    @property
    def checked(self) -> bool:
        return len(self.used) >= MIN_CHECKED

    @property
    def chi2_per_dof(self) -> float:
        return self.chi2 / self.dof if self.dof else math.nan

    def worst_check_pct(self) -> float:
        """The largest leave-one-out miss, % (NaN unchecked)."""
        return max((abs(c.miss_pct) for c in self.checks), default=math.nan)


def fit_scale(targets: Sequence[LaserTarget], profile: RigProfile, *,
              held_out: Sequence[LaserTarget] = (), overrule: bool = False) -> ScaleFit:
    """The scale the ``targets`` (of runs with ``profile``'s geometry) imply, and the
    ``held_out`` targets checked against it. The priors: the profile's tolerances for a
    and k, and for the laser's additive constant its readings' own sigma (the median of
    the targets'). ``overrule``: a prior the lasers find beyond its tolerance is left
    out (the user says the tape is wrong) instead of refused.
    InputError (one line, naming the targets) where none is usable, a blunder cannot be
    told from another row, too many are blunders, a prior is beyond its tolerance, or the
    runs are not one rig."""
    usable = [t for t in targets if _usable(t)]
    if not usable:
        raise InputError("no laser target with both a reading and a depth estimate: "
                         "nothing to calibrate the scale from")
    usable, duplicates = _merge_duplicates(usable)
    laser = max(float(np.median([t.laser_sigma_m for t in usable])), MIN_CONSTANT_SIGMA_M)
    priors = dict(zip(PRIORS, (*_priors(profile), laser), strict=True))
    tolerances = dict(priors)
    kept, rejected, overruled = snoop(usable, priors, tolerances, overrule, profile)
    adj = final_adjustment(kept, priors, tolerances)
    _plausible(adj, kept, profile)
    chance = chi2_chance(adj.chi2, adj.dof) if adj.dof else math.nan
    runs, one_rig = _one_rig(kept, adj)
    if adj.dof and chance < CONSISTENT_P:
        worst = int(np.argmax(np.abs(adj.standardised())))
        raise InputError(
            f"the laser targets and the profile disagree beyond their sigmas with no one "
            f"of them to blame (chi-square {adj.chi2:.1f} on {adj.dof} degrees of freedom, "
            f"chance {chance:.1g}; the worst is {adj.names[worst]}): a shape error or a "
            "wrong focal length? check the targets, or calibrate each session alone")
    sigma0 = math.sqrt(adj.chi2 / adj.dof) if adj.dof else math.nan
    inflate = max(1.0, sigma0**2) if adj.dof else 1.0
    cov = adj.cov * inflate
    a, k, c = adj.params
    constant_sigma = float(math.sqrt(cov[2, 2]))
    return ScaleFit(
        scale=float(k), scale_sigma=math.hypot(math.sqrt(cov[1, 1]), _offsets_share(kept)),
        map_scale_sigma=float(math.sqrt(cov[1, 1])),
        shape=float(a), shape_sigma=float(math.sqrt(cov[0, 0])), shape_fitted=not adj.held,
        used=tuple(kept),
        checks=tuple(_leave_out(t, kept, priors, adj.model) for t in kept)
        if len(kept) >= MIN_CHECKED else (),
        chi2=adj.chi2, dof=adj.dof, chance=chance, sigma0=sigma0,
        reference_m=_reference(kept),
        residuals=_residual_table(adj),
        rejected=tuple(rejected), duplicates=tuple(duplicates), overruled=tuple(overruled),
        held_out=tuple(_held_check(t, adj, inflate) for t in held_out if _usable(t)),
        runs=runs, one_rig_chance=one_rig,
        laser_constant_m=(float(c), constant_sigma),
        laser_constant_prior_m=tolerances[PRIOR_CONSTANT],
        laser_constant_seen=PRIOR_CONSTANT not in priors
        or constant_sigma < CONSTANT_SEEN * tolerances[PRIOR_CONSTANT],
        shape_targets_sigma=shape_sigma_alone(kept, priors),
    )


PLAUSIBLE = (0.5, 2.0)
"""The factors of C_lb and f*C_lr a calibration may find: beyond them the lasers measured
something else (a tape is not off by half)."""


def _plausible(adj: Adjustment, targets: Sequence[LaserTarget], profile: RigProfile
               ) -> None:
    a, k, _ = adj.params
    if PLAUSIBLE[0] <= k <= PLAUSIBLE[1] and PLAUSIBLE[0] <= a <= PLAUSIBLE[1]:
        return
    names = ", ".join(t.name for t in targets)
    raise InputError(
        f"the lasers ({names}) imply C_lb = {profile.baseline_lb.value_m * k:.3f} m and "
        f"f*C_lr x {a:.3f}: no rig is that far off its tape; the readings measured "
        "something else (a laser on something nearer?): check them")


def _usable(t: LaserTarget) -> bool:
    values = (t.laser_m, t.estimate_m, t.reference_m)
    return all(math.isfinite(v) and v > 0 for v in values) and all(
        math.isfinite(s) and s >= 0 for s in (t.laser_sigma_m, t.estimate_sigma_m))


Copies = list[tuple[LaserTarget, tuple[LaserTarget, ...]]]
"""Targets and the copies of each merged into it."""


def _merge_duplicates(targets: list[LaserTarget]) -> tuple[list[LaserTarget], Copies]:
    """One target per (run, pixel, reading): copies under other names are the same
    observation and count once."""
    kept: dict[tuple[str, object, float], LaserTarget] = {}
    copies: dict[str, list[LaserTarget]] = {}
    for t in targets:
        pixel = None if t.pixel is None else (round(t.pixel[0]), round(t.pixel[1]))
        key = (t.run, pixel if pixel is not None else t.name, round(t.laser_m, 6))
        if key in kept:
            copies.setdefault(kept[key].name, []).append(t)
        else:
            kept[key] = t
    out = list(kept.values())
    return out, [(t, tuple(copies[t.name])) for t in out if t.name in copies]


def twins(t: LaserTarget, others: Sequence[LaserTarget]) -> list[LaserTarget]:
    """``t`` and the targets of its run whose windows overlap its own (they share depth
    pixels, so their estimates are not independent)."""
    if t.pixel is None:
        return [t]
    group = [o for o in others if o is not t and o.run == t.run and o.pixel is not None
             and _overlap(t, o)]
    return [t, *group]


def _overlap(a: LaserTarget, b: LaserTarget) -> bool:
    assert a.pixel is not None and b.pixel is not None
    reach = (max(a.window_px, 1) + max(b.window_px, 1)) / 2
    return abs(a.pixel[0] - b.pixel[0]) < reach and abs(a.pixel[1] - b.pixel[1]) < reach


def _priors(profile: RigProfile) -> tuple[float, float]:
    """The relative one-sigma of f * C_lr and of C_lb the profile claims (its tolerances;
    :data:`UNSTATED_TOLERANCE` for one it leaves at 0)."""
    f, lr = shape_tolerances(profile)
    return math.hypot(f, lr), profile.baseline_lb.relative_tolerance or UNSTATED_TOLERANCE


def shape_tolerances(profile: RigProfile) -> tuple[float, float]:
    """The relative tolerances of f and of C_lr (:data:`UNSTATED_TOLERANCE` for 0)."""
    return (profile.focal_tolerance or UNSTATED_TOLERANCE,
            profile.baseline_lr.relative_tolerance or UNSTATED_TOLERANCE)


def _residual_table(adj: Adjustment) -> tuple[Residual, ...]:
    w, r = adj.standardised(), adj.redundancy()
    out = []
    for i, name in enumerate(adj.names):
        if i < len(adj.targets):
            t = adj.targets[i]
            out.append(Residual(name, prediction(t, adj)[1], float(w[i]), float(r[i]), t))
        else:
            column = PRIORS.index(name)
            value = adj.params[column] - FIXED[column]
            out.append(Residual(name, value if name == PRIOR_CONSTANT else 100 * value,
                                float(w[i]), float(r[i])))
    return tuple(out)


def _leave_out(t: LaserTarget, targets: Sequence[LaserTarget], priors: dict[str, float],
               model: Model) -> Check:
    """``t`` under the fit without it and its twins."""
    group = twins(t, targets)
    others = [x for x in targets if not any(x is g for g in group)]
    try:
        adj = adjust(others, priors, model)
    except InputError:
        adj = adjust(others, priors, HELD)
    calibrated, miss, sigma = prediction(t, adj)
    return Check(t, float(calibrated), miss, sigma)


def _held_check(t: LaserTarget, adj: Adjustment, inflate: float) -> Check:
    """A held-out target against the final fit (its covariance scaled as written)."""
    scaled = replace(adj, cov=adj.cov * inflate)
    calibrated, miss, sigma = prediction(t, scaled)
    return Check(t, float(calibrated), miss, sigma)


def _reference(targets: Sequence[LaserTarget]) -> float:
    """The depth the fit pins the scale at: the median of its runs' reference depths."""
    return float(np.median([t.reference_m for t in targets]))


def _offsets_share(targets: Sequence[LaserTarget]) -> float:
    """The runs' offset errors in C_lb's factor, one sigma: each run's own, combined
    over independent runs by their inverse variances (0 where a run states none)."""
    runs = {t.run: t.offset_fraction for t in targets}
    if any(f <= 0 for f in runs.values()):
        return 0.0
    return 1 / math.sqrt(sum(1 / f**2 for f in runs.values()))


def _one_rig(targets: Sequence[LaserTarget], adj: Adjustment
             ) -> tuple[tuple[RunScale, ...], float]:
    """Each run's own scale (its targets alone, f*C_lr as fitted) and the chance that
    one rig gives scales as far apart; InputError below ONE_RIG_P."""
    names = list(dict.fromkeys(t.run for t in targets))
    scales = []
    for run in names:
        own = [t for t in targets if t.run == run]
        design, y, sigma = observation_rows(own)
        a, _, c = adj.params
        rhs = (y - a * design[:, 0] - c * design[:, 2]) / sigma
        column = design[:, 1] / sigma
        k = float(column @ rhs / (column @ column))
        fit_sigma = math.sqrt(1 / float(column @ column))
        label = own[0].name.rsplit("/", 1)[0] if "/" in own[0].name else run
        scales.append(RunScale(label, k, math.hypot(fit_sigma, own[0].offset_fraction),
                               len(own)))
    if len(scales) < 2:
        return tuple(scales), math.nan
    factors = np.array([s.scale for s in scales])
    weights = 1 / np.array([s.sigma for s in scales]) ** 2
    mean = float(weights @ factors / weights.sum())
    chi2 = float(weights @ (factors - mean) ** 2)
    chance = chi2_chance(chi2, len(scales) - 1)
    if chance < ONE_RIG_P:
        said = "; ".join(f"{s.run}: x {s.scale:.4f} +- {s.sigma:.4f}" for s in scales)
        raise InputError(
            f"the sessions do not share one scale (chance {chance:.1g} for one rig): C_lb's "
            f"factor {said}: were they taken with one rig, taped once? calibrate each "
            "alone")
    return tuple(scales), chance
