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

Ideas credited: the a-priori values as observations, the test of the variance of unit
weight and data snooping with standardised residuals are the textbook geodetic
adjustment (Baarda 1968, "A testing procedure for use in geodetic networks").
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field, replace

import numpy as np

from rigkit.errors import InputError
from rigkit.rig.profile import Baseline, Calibration, RangefinderSpec, RigProfile

CRITICAL_W = 3.29
"""A standardised residual beyond this marks a blunder (two-sided alpha 0.001, Baarda's
usual critical value for data snooping)."""
GROSS_W = 10.0
"""Gross errors are found first, each target alone against the profile's values beyond
this many sigmas (its own, the tape's and the stretch f*C_lr's tolerance allows): about
10 % off under a 2 cm tape; two wild readings would otherwise drag the fit between them
and hide each other."""
INSEPARABLE_RHO = 0.9
"""Two rows whose standardised residuals correlate beyond this cannot be told apart: a
blunder in either looks the same."""
GLOBAL_P = 0.05
"""The global test: a chi-square with a smaller chance than this says the rows scatter
more than their sigmas (the covariance is then scaled by the variance of unit weight)."""
CONSISTENT_P = 1e-4
"""Rows whose chi-square has a smaller chance than this, with no single blunder to
blame, disagree with each other: nothing is fitted."""
ONE_RIG_P = 1e-3
"""Sessions whose scales differ with a smaller chance than this are not one rig."""
SHAPE_FLOOR = 5e-4
"""Relative error of a target's depth beyond its sigma (the pipeline's shape error at a
target's window on rendered scenes; benchmarks/bench_calibrate.py)."""
MIN_CHECKED = 3
"""Fewer targets than this calibrate the scale but leave it unchecked."""
UNSTATED_TOLERANCE = 0.01
"""The relative tolerance taken for f, C_lr or C_lb where a profile states none (0): a
lens spec's ~1 %, a tape's 2 cm on 2 m."""
GOAL_PCT = 1.0
"""The agreement a check is counted against, % of the range (the field verdict's goal)."""

PRIOR_SHAPE = "f*C_lr"
PRIOR_SCALE = "C_lb"
PRIOR_CONSTANT = "laser c"
_PRIORS = (PRIOR_SHAPE, PRIOR_SCALE, PRIOR_CONSTANT)
"""The a-priori rows, in the order of the unknowns a, k, c."""
_PRIOR_WORDS = {PRIOR_SHAPE: "the profile's f and C_lr (lens spec and tape)",
                PRIOR_SCALE: "the tape's C_lb",
                PRIOR_CONSTANT: "the laser's additive constant (a priori 0)"}
MIN_CONSTANT_SIGMA_M = 0.01
"""The least a-priori sigma of the laser's additive constant, m (readings stated exact
still have one to a centimetre)."""
CONSTANT_SEEN = 0.5
"""The laser's additive constant is determined by the targets (and written into the
profile's rangefinder offset) where they bring its sigma below this share of its prior's."""


@dataclass(frozen=True)
class LaserTarget:
    """One target of one run. ``laser_m``, ``estimate_m``: ranges, m; their one-sigma
    errors, m (``estimate_sigma_m`` the independent part); ``reference_m``: the run's
    reference depth z0, m (its depth map's median); ``run``: which run (session) it
    belongs to, and ``offset_fraction`` that run's disparity offset's one-sigma share of
    depth at z0, common to all of the run's targets. ``pixel`` (u, v, px) and
    ``window_px`` place it in its run's depth map (None: unknown), so twins are found."""

    name: str
    laser_m: float
    laser_sigma_m: float
    estimate_m: float
    estimate_sigma_m: float
    reference_m: float
    run: str = ""
    offset_fraction: float = 0.0
    pixel: tuple[float, float] | None = None
    window_px: int = 0


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
class Rejected:
    """A target left out as a blunder: its standardised residual when it was, and its
    miss against the fit without it, % of range."""

    target: LaserTarget
    miss_pct: float
    w: float


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


# ---------------------------------------------------------------------- the adjustment


@dataclass(frozen=True)
class _Model:
    """Which unknowns an adjustment fits beside k and c (the laser's additive constant,
    m, always, with its prior): a, f*C_lr's factor, where ``shape`` (else held at 1)."""

    shape: bool


HELD = _Model(False)


@dataclass(frozen=True)
class _Adjustment:
    """One weighted least squares: ``params`` (a, k, c), those held at 1, 1 and 0 where
    ``model`` says, their covariance (3, 3) (a priori, not scaled; zero for the held),
    the rows' names, whitened residuals (fit minus observation over sigma), the hat
    matrix (rows, rows), chi-square and dof."""

    params: np.ndarray
    cov: np.ndarray
    names: tuple[str, ...]
    residuals: np.ndarray
    hat: np.ndarray
    chi2: float
    dof: int
    model: _Model
    targets: tuple[LaserTarget, ...] = field(default=())

    @property
    def held(self) -> bool:
        return not self.model.shape

    def redundancy(self) -> np.ndarray:
        return np.clip(1.0 - np.diag(self.hat), 0.0, 1.0)

    def standardised(self) -> np.ndarray:
        """Each row's w (0 where it has no redundancy: nothing can check it)."""
        r = self.redundancy()
        with np.errstate(divide="ignore", invalid="ignore"):
            w = np.where(r > 1e-9, self.residuals / np.sqrt(r), 0.0)
        return np.asarray(w)

    def correlation(self, i: int) -> np.ndarray:
        """How row i's w correlates with every row's (NaN where one has no redundancy)."""
        r = self.redundancy()
        with np.errstate(divide="ignore", invalid="ignore"):
            rho = -self.hat[i] / np.sqrt(r[i] * r)
        rho[i] = 1.0
        return np.where(r > 1e-9, rho, np.nan)


def _rows(targets: Sequence[LaserTarget]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Design (n, 3) for (a, k, c), observations 1/e (n,) and their sigma (n,), in 1/m.
    A laser reading c long: 1/(t - c) = 1/t + c/t**2 to first order (times a ~ 1)."""
    t = np.array([x.laser_m for x in targets], float)
    e = np.array([x.estimate_m for x in targets], float)
    z0 = np.array([x.reference_m for x in targets], float)
    sigma_e = np.hypot([x.estimate_sigma_m for x in targets], SHAPE_FLOOR * e)
    sigma_t = np.array([x.laser_sigma_m for x in targets], float)
    design = (np.column_stack([1 / t - 1 / z0, 1 / z0, 1 / t**2]) if len(targets)
              else np.zeros((0, 3)))
    return design, 1 / e, np.hypot(sigma_e / e**2, sigma_t / t**2)


_FIXED = np.array([1.0, 1.0, 0.0])
"""The values of a, k and c where they are held."""


def _adjust(targets: Sequence[LaserTarget], priors: dict[str, float], model: _Model
            ) -> _Adjustment:
    """(a, k, c) from ``targets`` and the ``priors`` present (name -> sigma: relative
    for a and k, rows a = 1 and k = 1; m for c, row c = 0), a held at 1 where ``model``
    says. InputError where the rows do not determine the unknowns."""
    design, y, sigma = _rows(targets)
    names = [t.name for t in targets]
    free = np.array([model.shape, True, True])
    for column, name in enumerate(_PRIORS):
        if name in priors and free[column]:
            row = np.zeros((1, 3))
            row[0, column] = 1.0
            design, y = np.vstack([design, row]), np.append(y, _FIXED[column])
            sigma = np.append(sigma, priors[name])
            names.append(name)
    y = y - design[:, ~free] @ _FIXED[~free]
    A, b = design[:, free] / sigma[:, None], y / sigma
    normal = A.T @ A
    if len(b) < A.shape[1] or np.linalg.cond(normal) > 1e14:
        raise InputError("the laser targets do not determine the scale (too few, or all "
                         "at one range where f*C_lr is free)")
    inverse = np.linalg.inv(normal)
    solution = inverse @ A.T @ b
    residuals = A @ solution - b
    params, cov = _FIXED.copy(), np.zeros((3, 3))
    params[free] = solution
    cov[np.ix_(free, free)] = inverse
    return _Adjustment(params, cov, tuple(names), residuals, A @ inverse @ A.T,
                       float(residuals @ residuals), len(b) - A.shape[1], model,
                       tuple(targets))


def _prediction(t: LaserTarget, adj: _Adjustment) -> tuple[float, float, float]:
    """The calibrated range (m) of ``t``'s estimate under ``adj``, its miss against the
    laser (less the fitted constant) and that miss's sigma, both % of range."""
    design, y, sigma = _rows([t])
    a, k, c = adj.params
    predicted = float(design[0] @ adj.params)
    spread = float(design[0] @ adj.cov @ design[0])
    calibrated = a / (y[0] - (k - a) / t.reference_m)
    miss_sigma = math.sqrt(sigma[0] ** 2 + spread) / abs(predicted) * 100
    return calibrated, 100 * (calibrated - (t.laser_m - c)) / t.laser_m, miss_sigma


# ---------------------------------------------------------------------- the fit


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
    priors = dict(zip(_PRIORS, (*_priors(profile), laser), strict=True))
    tolerances = dict(priors)
    kept, rejected, overruled = _snoop(usable, priors, tolerances, overrule, profile)
    adj = _final(kept, priors, tolerances)
    _plausible(adj, kept, profile)
    chance = _chance(adj.chi2, adj.dof) if adj.dof else math.nan
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
        shape_targets_sigma=_shape_sigma_alone(kept, priors),
    )


PLAUSIBLE = (0.5, 2.0)
"""The factors of C_lb and f*C_lr a calibration may find: beyond them the lasers measured
something else (a tape is not off by half)."""


def _plausible(adj: _Adjustment, targets: Sequence[LaserTarget], profile: RigProfile
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
    f, lr = _shape_tolerances(profile)
    return math.hypot(f, lr), profile.baseline_lb.relative_tolerance or UNSTATED_TOLERANCE


def _shape_tolerances(profile: RigProfile) -> tuple[float, float]:
    """The relative tolerances of f and of C_lr (:data:`UNSTATED_TOLERANCE` for 0)."""
    return (profile.focal_tolerance or UNSTATED_TOLERANCE,
            profile.baseline_lr.relative_tolerance or UNSTATED_TOLERANCE)


def _sees_shape(targets: Sequence[LaserTarget], priors: dict[str, float],
                tolerances: dict[str, float]) -> bool:
    """Whether the targets alone (with C_lb's prior, not f*C_lr's) determine a better
    than the profile's own tolerances do; never with fewer than MIN_CHECKED targets (two
    targets would fit a stretch through any two readings)."""
    if len(targets) < MIN_CHECKED:
        return False
    return _shape_sigma_alone(targets, priors) < tolerances[PRIOR_SHAPE]


def _shape_sigma_alone(targets: Sequence[LaserTarget], priors: dict[str, float]) -> float:
    """The sigma of a from the targets and C_lb's prior only (inf where undetermined)."""
    try:
        adj = _adjust(targets, {k: v for k, v in priors.items() if k != PRIOR_SHAPE},
                      _Model(True))
    except InputError:
        return math.inf
    return float(math.sqrt(adj.cov[0, 0]))


def _final(targets: Sequence[LaserTarget], priors: dict[str, float],
           tolerances: dict[str, float]) -> _Adjustment:
    """The adjustment of ``targets`` with a fitted where they see it, else held at 1."""
    return _adjust(targets, priors, _Model(_sees_shape(targets, priors, tolerances)))


def _snoop(targets: list[LaserTarget], priors: dict[str, float],
           tolerances: dict[str, float], overrule: bool, profile: RigProfile
           ) -> tuple[list[LaserTarget], list[Rejected], list[tuple[str, float]]]:
    """Gross errors first, then data snooping: leave out the worst row beyond
    CRITICAL_W and adjust again, until none is. Changes ``priors`` where one is
    overruled. InputError where the worst cannot be told from another row, is a prior
    not overruled, or would leave as many targets out as in."""
    targets, rejected = _without_gross(targets, priors, overrule)
    overruled: list[tuple[str, float]] = []
    while True:
        adj = _final(targets, priors, tolerances)
        w = adj.standardised()
        worst = int(np.argmax(np.abs(w))) if len(w) else 0
        if not len(w) or abs(w[worst]) <= CRITICAL_W:
            return targets, rejected, overruled
        rho = np.nan_to_num(adj.correlation(worst))
        suspects = [adj.names[j] for j in range(len(w))
                    if j == worst or abs(rho[j]) >= INSEPARABLE_RHO]
        blamed = [n for n in suspects if n in priors and _determined(targets, priors, n)]
        if overrule and blamed:  # the user says the profile's value is what is wrong
            overruled.append((blamed[0], float(abs(w[worst]))))
            del priors[blamed[0]]
            continue
        name = suspects[0] if len(suspects) == 1 else _arbitrate(suspects, targets, priors)
        if name is None:
            raise InputError(_inseparable(suspects, w[worst], targets, rejected))
        if name in priors:
            raise InputError(_beyond_tolerance(name, targets, priors, w[worst], tolerances,
                                               profile))
        bad = next(t for t in targets if t.name == name)
        miss = _miss(bad, targets, priors, tolerances)
        _minority(len(targets) + len(rejected), [*rejected, Rejected(bad, miss, abs(w[worst]))])
        rejected.append(Rejected(bad, miss, float(abs(w[worst]))))
        targets = [t for t in targets if t is not bad]


def _determined(targets: Sequence[LaserTarget], priors: dict[str, float], name: str) -> bool:
    """Whether the targets determine the unknowns without the prior ``name``."""
    try:
        _adjust(targets, {k: v for k, v in priors.items() if k != name}, HELD)
    except InputError:
        return False
    return True


def _minority(count: int, rejected: Sequence[Rejected]) -> None:
    """InputError naming ``rejected`` where they are not fewer than the targets kept."""
    if count - len(rejected) > len(rejected):
        return
    worst = max(rejected, key=lambda r: r.w)
    named = ", ".join(r.target.name for r in rejected)
    verb = "disagrees" if len(rejected) == 1 else "disagree"
    raise InputError(
        f"{named} {verb} with the other targets and the profile beyond their sigmas (the "
        f"worst, {worst.target.name}, by {worst.miss_pct:+.1f} %, w = {worst.w:.1f}); with "
        f"{count} targets no more can be left out: check their readings (a laser on "
        "something nearer?), or hold them out (--hold-out)")


def _without_gross(targets: list[LaserTarget], priors: dict[str, float], overrule: bool
                   ) -> tuple[list[LaserTarget], list[Rejected]]:
    """The targets without gross errors: each one judged alone against the profile's
    values, beyond :data:`GROSS_W` (so two wild readings cannot hide each other, as they
    do in a fit they drag between them). None where the profile's values are overruled."""
    if overrule or PRIOR_SCALE not in priors or len(targets) < MIN_CHECKED:
        return targets, []
    scores = [_prior_score(t, priors) for t in targets]
    gross = [Rejected(t, _prior_miss(t), score)
             for t, score in zip(targets, scores, strict=True) if score > GROSS_W]
    if gross:
        _minority(len(targets), gross)
    return [t for t in targets if not any(t is g.target for g in gross)], gross


def _prior_score(t: LaserTarget, priors: dict[str, float]) -> float:
    """How many sigmas the C_lb factor ``t`` alone implies (f*C_lr at 1) lies from the
    tape's, its sigma widened by the stretch f*C_lr's tolerance allows at its range."""
    design, y, sigma = _rows([t])
    k = (y[0] - design[0, 0]) / design[0, 1]
    spread = math.hypot(sigma[0] / design[0, 1], priors[PRIOR_SCALE],
                        priors.get(PRIOR_SHAPE, 0.0) * abs(t.reference_m / t.laser_m - 1))
    return float(abs(k - 1) / spread)


def _prior_miss(t: LaserTarget) -> float:
    """``t``'s estimate against its laser, % of range, under the profile as it is."""
    return 100 * (t.estimate_m - t.laser_m) / t.laser_m


def _arbitrate(suspects: list[str], targets: Sequence[LaserTarget],
               priors: dict[str, float]) -> str | None:
    """Of targets the others cannot tell apart, the one the profile's own values say is
    the blunder: the worst of those the priors alone reject, where at least one of them
    agrees with the priors (None: a prior is among them, or the priors cannot tell)."""
    if any(name in priors for name in suspects) or PRIOR_SCALE not in priors:
        return None
    scores = {name: _prior_score(next(x for x in targets if x.name == name), priors)
              for name in suspects}
    bad = [n for n, score in scores.items() if score > CRITICAL_W]
    if not bad or len(bad) == len(scores):
        return None
    return max(bad, key=scores.__getitem__)


def _miss(t: LaserTarget, targets: Sequence[LaserTarget], priors: dict[str, float],
          tolerances: dict[str, float]) -> float:
    """``t``'s miss against the fit of the other targets, % of range."""
    others = [x for x in targets if x is not t]
    try:
        return _prediction(t, _final(others, priors, tolerances))[1]
    except InputError:
        return math.nan


def _inseparable(suspects: list[str], w: float, targets: Sequence[LaserTarget],
                 rejected: Sequence[Rejected]) -> str:
    named = [n for n in suspects if not (n == PRIOR_CONSTANT and PRIOR_SCALE in suspects)]
    words = [_PRIOR_WORDS.get(n, n) for n in named]
    count = len(targets)
    before = (f"{', '.join(r.target.name for r in rejected)} left out as blunders, then "
              if rejected else "")
    return (f"{before}{' and '.join(words)} disagree beyond their sigmas (w = {abs(w):.1f}), "
            f"and {count} target{'s' if count != 1 else ''} cannot tell which is wrong: check "
            "those readings (a laser on something nearer?) or add targets; nothing fitted")


def _beyond_tolerance(name: str, targets: Sequence[LaserTarget], priors: dict[str, float],
                      w: float, tolerances: dict[str, float], profile: RigProfile) -> str:
    """The refusal of a prior the lasers find beyond its tolerance, naming them."""
    alone = {k: v for k, v in priors.items() if k != name}
    column = _PRIORS.index(name)
    model = _Model(column == 0 or _sees_shape(targets, alone, tolerances))
    try:
        adj = _adjust(targets, alone, model)
        value, sigma = adj.params[column], math.sqrt(adj.cov[column, column])
    except InputError:
        value = sigma = math.nan
    lb = profile.baseline_lb
    if name == PRIOR_SCALE:
        said = f"C_lb at {lb.value_m * value:.4f} +- {lb.value_m * sigma:.4f} m"
        prior = f"the tape's {lb.value_m:.4f} +- {lb.value_m * tolerances[name]:.4f} m"
        fix = "re-tape C_lb"
    elif name == PRIOR_CONSTANT:
        said = f"the laser's additive constant at {value:+.2f} +- {sigma:.2f} m"
        prior = f"its a-priori 0 +- {tolerances[name]:.2f} m (one reading's sigma)"
        fix = "check the rangefinder's offset in the profile and the laser's own setting"
    else:
        said = f"f*C_lr at x {value:.4f} +- {sigma:.4f} of the profile's"
        prior = f"the profile's f and C_lr (+-{100 * tolerances[name]:.2f} %)"
        fix = "check the zoom, f and C_lr"
    names = ", ".join(t.name for t in targets)
    return (f"the lasers ({names}) put {said}, beyond {prior} (w = {abs(w):.1f}): {fix} "
            "and process again, or, if the profile's value is what is wrong, give "
            "--beyond-tolerance to let the lasers overrule it")


def _residual_table(adj: _Adjustment) -> tuple[Residual, ...]:
    w, r = adj.standardised(), adj.redundancy()
    out = []
    for i, name in enumerate(adj.names):
        if i < len(adj.targets):
            t = adj.targets[i]
            out.append(Residual(name, _prediction(t, adj)[1], float(w[i]), float(r[i]), t))
        else:
            column = _PRIORS.index(name)
            value = adj.params[column] - _FIXED[column]
            out.append(Residual(name, value if name == PRIOR_CONSTANT else 100 * value,
                                float(w[i]), float(r[i])))
    return tuple(out)


def _leave_out(t: LaserTarget, targets: Sequence[LaserTarget], priors: dict[str, float],
               model: _Model) -> Check:
    """``t`` under the fit without it and its twins."""
    group = twins(t, targets)
    others = [x for x in targets if not any(x is g for g in group)]
    try:
        adj = _adjust(others, priors, model)
    except InputError:
        adj = _adjust(others, priors, HELD)
    calibrated, miss, sigma = _prediction(t, adj)
    return Check(t, float(calibrated), miss, sigma)


def _held_check(t: LaserTarget, adj: _Adjustment, inflate: float) -> Check:
    """A held-out target against the final fit (its covariance scaled as written)."""
    scaled = replace(adj, cov=adj.cov * inflate)
    calibrated, miss, sigma = _prediction(t, scaled)
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


def _one_rig(targets: Sequence[LaserTarget], adj: _Adjustment
             ) -> tuple[tuple[RunScale, ...], float]:
    """Each run's own scale (its targets alone, f*C_lr as fitted) and the chance that
    one rig gives scales as far apart; InputError below ONE_RIG_P."""
    names = list(dict.fromkeys(t.run for t in targets))
    scales = []
    for run in names:
        own = [t for t in targets if t.run == run]
        design, y, sigma = _rows(own)
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
    chance = _chance(chi2, len(scales) - 1)
    if chance < ONE_RIG_P:
        said = "; ".join(f"{s.run}: x {s.scale:.4f} +- {s.sigma:.4f}" for s in scales)
        raise InputError(
            f"the sessions do not share one scale (chance {chance:.1g} for one rig): C_lb's "
            f"factor {said}: were they taken with one rig, taped once? calibrate each "
            "alone")
    return tuple(scales), chance


def _chance(chi2: float, dof: int) -> float:
    """P(X >= chi2) for a chi-square of ``dof`` degrees of freedom."""
    from scipy.stats import chi2 as distribution

    return float(distribution.sf(chi2, dof))


# ------------------------------------------------------------------ the profile it gives


@dataclass(frozen=True)
class CalibratedValues:
    """What a calibration changes in a profile and why: ``profile`` the new one,
    ``changes`` one line per value that changed (before -> after), ``kept`` one line per
    value the fit would have made worse for other captures (the tape kept)."""

    profile: RigProfile
    changes: tuple[str, ...]
    kept: tuple[str, ...]


def calibrated_profile(profile: RigProfile, fit: ScaleFit, record: Calibration
                       ) -> CalibratedValues:
    """``profile`` with C_lb (and, where fitted, f and C_lr) as the lasers say, their
    tolerances one sigma of the fit, ``record`` as its provenance and a name that says
    it is calibrated. C_lb stays the tape's where the fit knows it no better for other
    captures than the tape does. An error in f * C_lr is shared between f and C_lr in
    proportion to their prior variances (the lasers cannot tell them apart)."""
    lb = profile.baseline_lb
    changes: list[str] = []
    kept: list[str] = []
    tape = lb.relative_tolerance or UNSTATED_TOLERANCE
    baseline_lb = lb
    if fit.scale_sigma < tape:
        baseline_lb = Baseline(lb.value_m * fit.scale, lb.value_m * fit.scale_sigma)
        changes.append(f"C_lb {lb.value_m:.4f} +- {lb.tolerance_m:.4f} m -> "
                       f"{baseline_lb.value_m:.4f} +- {baseline_lb.tolerance_m:.4f} m")
    else:
        kept.append(f"C_lb kept at the tape's {lb.value_m:.4f} +- {lb.tolerance_m:.4f} m: "
                    f"the lasers know it to +-{100 * fit.scale_sigma:.2f} % for other "
                    f"captures, no better than the tape's +-{100 * tape:.2f} %")
    cameras, baseline_lr = dict(profile.cameras), profile.baseline_lr
    if fit.shape_fitted:
        tol_f, tol_c = _shape_tolerances(profile)
        share = tol_f**2 / (tol_f**2 + tol_c**2)
        f_factor, c_factor = fit.shape**share, fit.shape ** (1 - share)
        before_f, before_tol = profile.focal_px, profile.focal_tolerance
        for role, camera in cameras.items():
            focal = camera.focal_px * f_factor
            cameras[role] = replace(camera, focal_px=focal, focal_given=("px", focal),
                                    focal_tolerance=fit.shape_sigma * math.sqrt(share))
        baseline_lr = Baseline(baseline_lr.value_m * c_factor,
                               baseline_lr.value_m * c_factor * fit.shape_sigma
                               * math.sqrt(1 - share))
        changes.append(f"f {before_f:.1f} px +- {100 * before_tol:.2f} % -> "
                       f"{before_f * f_factor:.1f} px +- "
                       f"{100 * fit.shape_sigma * math.sqrt(share):.2f} %")
        lr = profile.baseline_lr
        changes.append(f"C_lr {lr.value_m:.4f} +- {lr.tolerance_m:.4f} m -> "
                       f"{baseline_lr.value_m:.4f} +- {baseline_lr.tolerance_m:.4f} m")
    rangefinder = _rangefinder(profile, fit, changes, kept)
    out = replace(profile, name=calibrated_name(profile.name, record.date_utc),
                  cameras=cameras, baseline_lr=baseline_lr, baseline_lb=baseline_lb,
                  rangefinder=rangefinder,
                  calibration=replace(record, changes=tuple(changes + kept)))
    return CalibratedValues(out, tuple(changes), tuple(kept))


MAX_LASER_OFFSET_M = 10.0
"""The largest rangefinder offset a profile takes (rig.profile's bound), m."""


def _rangefinder(profile: RigProfile, fit: ScaleFit, changes: list[str], kept: list[str]
                 ) -> RangefinderSpec | None:
    """The profile's rangefinder with the laser's additive constant, where the targets
    determine it, taken into its forward offset: a laser reading c long ranges from an
    aperture c behind where the profile put it."""
    spec = profile.rangefinder
    if not fit.laser_constant_seen:
        return spec
    c, sigma = fit.laser_constant_m
    spec = spec or RangefinderSpec("manual", None, None, None)
    right, up, forward = spec.offset_m or (0.0, 0.0, 0.0)
    if abs(forward - c) > MAX_LASER_OFFSET_M:
        kept.append(f"the laser's additive constant {c:+.2f} +- {sigma:.2f} m not written: "
                    f"it would put the rangefinder {forward - c:+.1f} m forward")
        return profile.rangefinder
    changes.append(f"rangefinder forward offset {forward:+.3f} m -> {forward - c:+.3f} m (the "
                   f"laser's additive constant {c:+.2f} +- {sigma:.2f} m)")
    return replace(spec, offset_m=(right, up, forward - c))


def calibrated_name(name: str, date_utc: str) -> str:
    """A profile's name once calibrated: its base (without ``-taped`` or an earlier
    calibration's suffix) and ``-laser-calibrated-YYYYMMDD``."""
    base = name.strip()
    for suffix in ("-taped", "_taped", " taped"):
        if base.lower().endswith(suffix):
            base = base[: -len(suffix)]
    marker = base.lower().rfind("-laser-calibrated-")
    if marker > 0:
        base = base[:marker]
    day = "".join(ch for ch in date_utc[:10] if ch.isdigit())
    return f"{base}-laser-calibrated-{day}"
