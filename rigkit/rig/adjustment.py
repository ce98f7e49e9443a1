"""The least squares behind ``rigkit rig calibrate`` (:mod:`rigkit.rig.calibration`):
each laser target a row of 1/e = a/t + (k - a)/z0 + c/t**2 in the unknowns a (f * C_lr's
factor), k (C_lb's) and c (the laser's additive constant, m), the profile's tolerances
a-priori rows a = 1, k = 1 and c = 0, weighted by their sigmas; the fit's residuals,
redundancy numbers and standardised residuals (what :mod:`rigkit.rig.blunders` snoops
with), and a target's prediction under a fit.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from rigkit.errors import InputError

SHAPE_FLOOR = 5e-4
"""Relative error of a target's depth beyond its sigma (the pipeline's shape error at a
target's window on rendered scenes; benchmarks/bench_calibrate.py)."""
MIN_CHECKED = 3
"""Fewer targets than this calibrate the scale but leave it unchecked."""
PRIOR_SHAPE = "f*C_lr"
PRIOR_SCALE = "C_lb"
PRIOR_CONSTANT = "laser c"
PRIORS = (PRIOR_SHAPE, PRIOR_SCALE, PRIOR_CONSTANT)
"""The a-priori rows, in the order of the unknowns a, k, c."""


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
class Model:
    """Which unknowns an adjustment fits beside k and c (the laser's additive constant,
    m, always, with its prior): a, f*C_lr's factor, where ``shape`` (else held at 1)."""

    shape: bool


HELD = Model(False)


@dataclass(frozen=True)
class Adjustment:
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
    model: Model
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


def observation_rows(targets: Sequence[LaserTarget]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
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


FIXED = np.array([1.0, 1.0, 0.0])
"""The values of a, k and c where they are held."""


def adjust(targets: Sequence[LaserTarget], priors: dict[str, float], model: Model
            ) -> Adjustment:
    """(a, k, c) from ``targets`` and the ``priors`` present (name -> sigma: relative
    for a and k, rows a = 1 and k = 1; m for c, row c = 0), a held at 1 where ``model``
    says. InputError where the rows do not determine the unknowns."""
    design, y, sigma = observation_rows(targets)
    names = [t.name for t in targets]
    free = np.array([model.shape, True, True])
    for column, name in enumerate(PRIORS):
        if name in priors and free[column]:
            row = np.zeros((1, 3))
            row[0, column] = 1.0
            design, y = np.vstack([design, row]), np.append(y, FIXED[column])
            sigma = np.append(sigma, priors[name])
            names.append(name)
    y = y - design[:, ~free] @ FIXED[~free]
    A, b = design[:, free] / sigma[:, None], y / sigma
    normal = A.T @ A
    if len(b) < A.shape[1] or np.linalg.cond(normal) > 1e14:
        raise InputError("the laser targets do not determine the scale (too few, or all "
                         "at one range where f*C_lr is free)")
    inverse = np.linalg.inv(normal)
    solution = inverse @ A.T @ b
    residuals = A @ solution - b
    params, cov = FIXED.copy(), np.zeros((3, 3))
    params[free] = solution
    cov[np.ix_(free, free)] = inverse
    return Adjustment(params, cov, tuple(names), residuals, A @ inverse @ A.T,
                       float(residuals @ residuals), len(b) - A.shape[1], model,
                       tuple(targets))


def prediction(t: LaserTarget, adj: Adjustment) -> tuple[float, float, float]:
    """The calibrated range (m) of ``t``'s estimate under ``adj``, its miss against the
    laser (less the fitted constant) and that miss's sigma, both % of range."""
    design, y, sigma = observation_rows([t])
    a, k, c = adj.params
    predicted = float(design[0] @ adj.params)
    spread = float(design[0] @ adj.cov @ design[0])
    calibrated = a / (y[0] - (k - a) / t.reference_m)
    miss_sigma = math.sqrt(sigma[0] ** 2 + spread) / abs(predicted) * 100
    return calibrated, 100 * (calibrated - (t.laser_m - c)) / t.laser_m, miss_sigma


def sees_shape(targets: Sequence[LaserTarget], priors: dict[str, float],
                tolerances: dict[str, float]) -> bool:
    """Whether the targets alone (with C_lb's prior, not f*C_lr's) determine a better
    than the profile's own tolerances do; never with fewer than MIN_CHECKED targets (two
    targets would fit a stretch through any two readings)."""
    if len(targets) < MIN_CHECKED:
        return False
    return shape_sigma_alone(targets, priors) < tolerances[PRIOR_SHAPE]


def shape_sigma_alone(targets: Sequence[LaserTarget], priors: dict[str, float]) -> float:
    """The sigma of a from the targets and C_lb's prior only (inf where undetermined)."""
    try:
        adj = adjust(targets, {k: v for k, v in priors.items() if k != PRIOR_SHAPE},
                      Model(True))
    except InputError:
        return math.inf
    return float(math.sqrt(adj.cov[0, 0]))


def final_adjustment(targets: Sequence[LaserTarget], priors: dict[str, float],
           tolerances: dict[str, float]) -> Adjustment:
    """The adjustment of ``targets`` with a fitted where they see it, else held at 1."""
    return adjust(targets, priors, Model(sees_shape(targets, priors, tolerances)))


def chi2_chance(chi2: float, dof: int) -> float:
    """P(X >= chi2) for a chi-square of ``dof`` degrees of freedom."""
    from scipy.stats import chi2 as distribution

    return float(distribution.sf(chi2, dof))
