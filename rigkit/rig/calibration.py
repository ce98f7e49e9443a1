"""The rig's scale from its own laser: C_lb, and f * C_lr where the targets span enough
depth to see it, fitted from laser ranges at pixels with an estimated depth.

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
laser's accuracy and the independent part of its depth sigma (the offset's share of
sigma is common to a session's targets: the fit measures it, it is not noise). ``a``
needs targets spread in depth: where they leave it no better known than the profile's
own tolerances (the posterior sigma above half the prior's) it is held at 1 and only
C_lb is fitted. A scale error and a C_lb error are the same thing: what is called C_lb
here is whatever makes the depth map's scale right.

The profile's tolerances are the priors (a, k ~ 1 +- the relative tolerance), so one
target calibrates the scale and a distant prior keeps a shapeless fit sane. A target
whose leave-one-out prediction misses by more than :data:`STRAY_SIGMAS` is a stray (a
laser on the wrong object, a typo): named and left out while enough targets remain;
targets that still disagree beyond their sigma (a shape error, a wrong f) stop the fit
with the target that breaks it. Targets that calibrated a rig cannot also prove it:
each target's check is its leave-one-out residual, the fit made without it.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np

from rigkit.errors import InputError
from rigkit.rig.profile import Baseline, RigProfile

STRAY_SIGMAS = 5.0
"""A target whose leave-one-out prediction misses by more than this many sigma is a stray."""
CONSISTENT_P = 1e-4
"""Targets whose chi-square has a smaller chance than this disagree with each other."""
SHAPE_FLOOR = 5e-4
"""Relative error of a target's depth beyond its sigma (the pipeline's shape error at a
target's window on rendered scenes; benchmarks/bench_calibrate.py)."""
FIT_SHAPE_BELOW = 0.5
"""f * C_lr is fitted where the targets bring its sigma below this share of the prior's."""
MIN_CHECKED = 3
"""Fewer targets than this calibrate the scale but leave it unchecked."""
UNSTATED_TOLERANCE = 0.01
"""The relative tolerance taken for f, C_lr or C_lb where a profile states none (0): a
lens spec's ~1 %, a tape's 2 cm on 2 m."""


@dataclass(frozen=True)
class LaserTarget:
    """One target of one run. ``laser_m``, ``estimate_m``: ranges, m; their one-sigma
    errors, m (``estimate_sigma_m`` the independent part); ``reference_m``: the run's
    reference depth z0, m (its depth map's median); ``run``: which run (session) it
    belongs to, and ``offset_fraction`` that run's disparity offset's one-sigma share of
    depth at z0, common to all of the run's targets."""

    name: str
    laser_m: float
    laser_sigma_m: float
    estimate_m: float
    estimate_sigma_m: float
    reference_m: float
    run: str = ""
    offset_fraction: float = 0.0


@dataclass(frozen=True)
class Check:
    """A target's leave-one-out check: the calibrated range (m) its estimate gives under
    the fit made without it, the miss against the laser and its sigma, % of range."""

    target: LaserTarget
    calibrated_m: float
    miss_pct: float
    sigma_pct: float


@dataclass(frozen=True)
class ScaleFit:
    """What the lasers say: ``scale`` = k (C_lb's factor) and ``shape`` = a (f * C_lr's),
    each with its one-sigma; ``shape_fitted`` False where a was held at 1; the targets
    used, the strays left out (with their misses, %), the leave-one-out ``checks``
    (empty below :data:`MIN_CHECKED` targets) and the chi-square per degree of freedom.

    ``map_scale_sigma`` is how well the targets fix the scale of the depth maps they
    came from; ``scale_sigma`` how well they know C_lb itself, for other captures: it
    adds the runs' offset errors, which shift all of a run's targets together and look
    exactly like a C_lb error there (several runs average them down)."""

    scale: float
    scale_sigma: float
    map_scale_sigma: float
    shape: float
    shape_sigma: float
    shape_fitted: bool
    used: tuple[LaserTarget, ...]
    strays: tuple[tuple[LaserTarget, float], ...]
    checks: tuple[Check, ...]
    chi2_per_dof: float

    @property
    def checked(self) -> bool:
        return len(self.used) >= MIN_CHECKED

    def worst_check_pct(self) -> float:
        """The largest leave-one-out miss, % (NaN unchecked)."""
        return max((abs(c.miss_pct) for c in self.checks), default=math.nan)


@dataclass(frozen=True)
class _Solution:
    params: np.ndarray  # (a, k)
    cov: np.ndarray  # (2, 2)
    chi2: float
    dof: int


def fit_scale(targets: Sequence[LaserTarget], profile: RigProfile) -> ScaleFit:
    """The scale the ``targets`` (of runs with ``profile``'s geometry) imply. InputError
    (one line, naming the target) where none is usable or they disagree."""
    used = [t for t in targets if _usable(t)]
    if not used:
        raise InputError("no laser target with both a reading and a depth estimate: "
                         "nothing to calibrate the scale from")
    priors = _priors(profile)
    used, strays = _without_strays(used, priors)
    shape_fitted = _sees_shape(used, priors)
    if not shape_fitted:
        priors = (0.0, priors[1])
    solution = _solve(used, priors)
    if solution.dof > 0 and _chance(solution.chi2, solution.dof) < CONSISTENT_P:
        _, miss, worst = _worst_miss(used, priors)
        raise InputError(
            f"the laser targets disagree with each other beyond their sigma: {worst.name} "
            f"misses the others' fit by {miss:+.2f} % (a laser on the wrong object, a shape "
            "error or a wrong focal length?); check it, or remove its readings")
    cov = solution.cov * max(1.0, solution.chi2 / solution.dof if solution.dof else 1.0)
    a, k = solution.params
    return ScaleFit(
        scale=float(k), scale_sigma=math.hypot(math.sqrt(cov[1, 1]), _offsets_share(used)),
        map_scale_sigma=float(math.sqrt(cov[1, 1])),
        shape=float(a), shape_sigma=float(math.sqrt(cov[0, 0])), shape_fitted=shape_fitted,
        used=tuple(used), strays=tuple(strays),
        checks=tuple(_check(t, used, priors) for t in used) if len(used) >= MIN_CHECKED
        else (),
        chi2_per_dof=solution.chi2 / solution.dof if solution.dof else math.nan,
    )


def _usable(t: LaserTarget) -> bool:
    values = (t.laser_m, t.estimate_m, t.reference_m)
    return all(math.isfinite(v) and v > 0 for v in values) and all(
        math.isfinite(s) and s >= 0 for s in (t.laser_sigma_m, t.estimate_sigma_m))


def _offsets_share(targets: Sequence[LaserTarget]) -> float:
    """The runs' offset errors in C_lb's factor, one sigma: each run's own, combined
    over independent runs by their inverse variances (0 where a run states none)."""
    runs = {t.run: t.offset_fraction for t in targets}
    if any(f <= 0 for f in runs.values()):
        return 0.0
    return 1 / math.sqrt(sum(1 / f**2 for f in runs.values()))


def _priors(profile: RigProfile) -> tuple[float, float]:
    """The relative one-sigma of f * C_lr and of C_lb the profile claims (its tolerances;
    :data:`UNSTATED_TOLERANCE` for one it leaves at 0)."""
    f, lr = _shape_tolerances(profile)
    return math.hypot(f, lr), profile.baseline_lb.relative_tolerance or UNSTATED_TOLERANCE


def _shape_tolerances(profile: RigProfile) -> tuple[float, float]:
    """The relative tolerances of f and of C_lr (:data:`UNSTATED_TOLERANCE` for 0)."""
    return (profile.focal_tolerance or UNSTATED_TOLERANCE,
            profile.baseline_lr.relative_tolerance or UNSTATED_TOLERANCE)


def _rows(targets: Sequence[LaserTarget]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Design (n, 2), observations 1/e (n,) and their sigma (n,), in 1/m."""
    t = np.array([x.laser_m for x in targets])
    e = np.array([x.estimate_m for x in targets])
    z0 = np.array([x.reference_m for x in targets])
    sigma_e = np.hypot([x.estimate_sigma_m for x in targets], SHAPE_FLOOR * e)
    sigma_t = np.array([x.laser_sigma_m for x in targets])
    design = np.column_stack([1 / t - 1 / z0, 1 / z0])
    return design, 1 / e, np.hypot(sigma_e / e**2, sigma_t / t**2)


def _solve(targets: Sequence[LaserTarget], priors: tuple[float, float]) -> _Solution:
    """Weighted least squares for (a, k) with the priors as observations a = 1, k = 1
    (a held at 1 where its prior is 0)."""
    design, y, sigma = _rows(targets)
    held = priors[0] == 0.0
    if held:  # a = 1 exactly: 1/e - (1/t - 1/z0) = k / z0
        y, design = y - design[:, 0], design[:, 1:]
    rows = [design / sigma[:, None]]
    obs = [y / sigma]
    for i, prior in enumerate(priors[1:] if held else priors):
        unit = np.zeros(design.shape[1])
        unit[i] = 1 / prior
        rows.append(unit[None, :])
        obs.append(np.array([1 / prior]))
    A, b = np.vstack(rows), np.concatenate(obs)
    params, *_ = np.linalg.lstsq(A, b, rcond=None)
    cov = np.linalg.inv(A.T @ A)
    # How far the targets disagree with each other: their own rows only, not a prior
    # the lasers overrule (an f 5 % off a profile claiming 1 % is a finding, not noise).
    n = len(y)
    chi2 = float(np.sum((A[:n] @ params - b[:n]) ** 2))
    dof = max(n - A.shape[1], 0)
    if held:
        params, cov = np.array([1.0, params[0]]), np.array([[0.0, 0.0], [0.0, cov[0, 0]]])
    return _Solution(params, cov, chi2, dof)


def _prediction(t: LaserTarget, solution: _Solution) -> tuple[float, float]:
    """A target's 1/e as ``solution`` predicts it, and the sigma of its miss."""
    design, y, sigma = _rows([t])
    predicted = float(design[0] @ solution.params)
    spread = float(design[0] @ solution.cov @ design[0])
    return predicted, math.sqrt(sigma[0] ** 2 + spread)


def _worst_miss(targets: Sequence[LaserTarget], priors: tuple[float, float]
                ) -> tuple[float, float, LaserTarget]:
    """The target whose estimate the fit without it misses by the most sigmas: those
    sigmas, the miss in % of range (negative: the estimate reads short) and the target."""
    worst = (-1.0, math.nan, targets[0])
    for t in targets:
        predicted, sigma = _prediction(t, _solve([x for x in targets if x is not t], priors))
        miss = 1 / t.estimate_m - predicted
        if abs(miss) / sigma > worst[0]:
            worst = (abs(miss) / sigma, -100 * miss * t.laser_m, t)
    return worst


def _without_strays(targets: list[LaserTarget], priors: tuple[float, float]
                    ) -> tuple[list[LaserTarget], list[tuple[LaserTarget, float]]]:
    """Leave out, worst first, targets whose leave-one-out miss exceeds STRAY_SIGMAS,
    while at least MIN_CHECKED remain and at most a quarter are left out."""
    strays: list[tuple[LaserTarget, float]] = []
    allowed = max(1, len(targets) // 4)
    while len(targets) > MIN_CHECKED and len(strays) < allowed:
        score, pct, worst = _worst_miss(targets, priors)
        if score <= STRAY_SIGMAS:
            break
        strays.append((worst, pct))
        targets = [t for t in targets if t is not worst]
    return targets, strays


def _sees_shape(targets: Sequence[LaserTarget], priors: tuple[float, float]) -> bool:
    """Whether the targets bring f * C_lr's sigma below FIT_SHAPE_BELOW of its prior."""
    return math.sqrt(_solve(targets, priors).cov[0, 0]) < FIT_SHAPE_BELOW * priors[0]


def _check(t: LaserTarget, targets: Sequence[LaserTarget], priors: tuple[float, float]
           ) -> Check:
    """The calibrated range of ``t`` under the fit without it, against its laser."""
    solution = _solve([x for x in targets if x is not t], priors)
    a, k = solution.params
    _, sigma = _prediction(t, solution)
    calibrated = a / (1 / t.estimate_m - (k - a) / t.reference_m)
    return Check(t, float(calibrated), 100 * (calibrated - t.laser_m) / t.laser_m,
                 100 * sigma * t.laser_m)


def _chance(chi2: float, dof: int) -> float:
    """P(X >= chi2) for a chi-square of ``dof`` degrees of freedom."""
    from scipy.stats import chi2 as distribution

    return float(distribution.sf(chi2, dof))


# ------------------------------------------------------------------ the profile it gives


def calibrated_profile(profile: RigProfile, fit: ScaleFit, note: str) -> RigProfile:
    """``profile`` with C_lb (and, where fitted, f and C_lr) as the lasers say, their
    tolerances one sigma of the fit; ``note`` is added to its notes. An error in f * C_lr
    is shared between f and C_lr in proportion to their prior variances (the lasers
    cannot tell them apart)."""
    lb = profile.baseline_lb
    baseline_lb = Baseline(lb.value_m * fit.scale, lb.value_m * fit.scale_sigma)
    cameras, baseline_lr = dict(profile.cameras), profile.baseline_lr
    if fit.shape_fitted:
        tol_f, tol_c = _shape_tolerances(profile)
        share = tol_f**2 / (tol_f**2 + tol_c**2)
        f_factor, c_factor = fit.shape**share, fit.shape ** (1 - share)
        for role, camera in cameras.items():
            focal = camera.focal_px * f_factor
            cameras[role] = replace(camera, focal_px=focal, focal_given=("px", focal),
                                    focal_tolerance=fit.shape_sigma * math.sqrt(share))
        baseline_lr = Baseline(baseline_lr.value_m * c_factor,
                               baseline_lr.value_m * c_factor * fit.shape_sigma
                               * math.sqrt(1 - share))
    notes = f"{profile.notes.rstrip()}\n{note}".strip()
    return replace(profile, cameras=cameras, baseline_lr=baseline_lr,
                   baseline_lb=baseline_lb, notes=notes)
