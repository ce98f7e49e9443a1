"""Blunders among a calibration's rows (:mod:`rigkit.rig.calibration`): gross errors
first, each target judged alone against the profile's values, then data snooping
(Baarda): the worst standardised residual beyond :data:`CRITICAL_W` left out and the
adjustment (:mod:`rigkit.rig.adjustment`) repeated; rows that cannot be told apart named
together, a prior found to be the blunder refused (or overruled where the user says so),
and never more than a minority of the targets left out.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from rigkit.errors import InputError
from rigkit.rig.adjustment import (
    HELD,
    MIN_CHECKED,
    PRIOR_CONSTANT,
    PRIOR_SCALE,
    PRIOR_SHAPE,
    PRIORS,
    LaserTarget,
    Model,
    adjust,
    final_adjustment,
    observation_rows,
    prediction,
    sees_shape,
)
from rigkit.rig.defaults import CRITICAL_W
from rigkit.rig.profile import RigProfile

GROSS_W = 10.0
"""Gross errors are found first, each target alone against the profile's values beyond
this many sigmas (its own, the tape's and the stretch f*C_lr's tolerance allows): about
10 % off under a 2 cm tape; two wild readings would otherwise drag the fit between them
and hide each other."""
INSEPARABLE_RHO = 0.9
"""Two rows whose standardised residuals correlate beyond this cannot be told apart: a
blunder in either looks the same."""
_PRIOR_WORDS = {PRIOR_SHAPE: "the profile's f and C_lr (lens spec and tape)",
                PRIOR_SCALE: "the tape's C_lb",
                PRIOR_CONSTANT: "the laser's additive constant (a priori 0)"}


@dataclass(frozen=True)
class Rejected:
    """A target left out as a blunder: its standardised residual when it was, and its
    miss against the fit without it, % of range."""

    target: LaserTarget
    miss_pct: float
    w: float


def snoop(targets: list[LaserTarget], priors: dict[str, float],
           tolerances: dict[str, float], overrule: bool, profile: RigProfile
           ) -> tuple[list[LaserTarget], list[Rejected], list[tuple[str, float]]]:
    """Gross errors first, then data snooping: leave out the worst row beyond
    CRITICAL_W and adjust again, until none is. Changes ``priors`` where one is
    overruled. InputError where the worst cannot be told from another row, is a prior
    not overruled, or would leave as many targets out as in."""
    targets, rejected = _without_gross(targets, priors, overrule)
    overruled: list[tuple[str, float]] = []
    while True:
        adj = final_adjustment(targets, priors, tolerances)
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
        adjust(targets, {k: v for k, v in priors.items() if k != name}, HELD)
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
    design, y, sigma = observation_rows([t])
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
        return prediction(t, final_adjustment(others, priors, tolerances))[1]
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
    column = PRIORS.index(name)
    model = Model(column == 0 or sees_shape(targets, alone, tolerances))
    try:
        adj = adjust(targets, alone, model)
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
