"""Statistics of the pipeline's small least-squares fits: a covariance that sees errors
shared within spatial blocks (heat shimmer moves whole patches of matches together),
and a test of whether a fitted change is more than its covariance explains."""

from __future__ import annotations

import numpy as np

from rigkit.core.lazy import function
from rigkit.core.threads import ViewPool

chdtri = function("scipy.special", "chdtri")


def significant_change(change: np.ndarray, cov: np.ndarray, confidence: float) -> bool:
    """Whether ``change`` (n,) from a start is more than its covariance (n, n) explains:
    its Mahalanobis distance against the chi-square quantile ``confidence`` with n
    degrees of freedom."""
    try:
        distance = float(change @ np.linalg.solve(cov, change))
    except np.linalg.LinAlgError:
        return False
    # chdtri(k, q): the chi-square quantile with k degrees of freedom exceeded with
    # probability q (scipy.special: scipy.stats would add 0.25 s to every command's start)
    return bool(np.isfinite(distance) and distance > chdtri(len(change), 1 - confidence))


def cluster_covariance(
    J: np.ndarray, r: np.ndarray, labels: np.ndarray, eliminated: int
) -> np.ndarray:
    """Cluster-robust ("sandwich") covariance of a least-squares fit with Jacobian J
    (n, P) and residuals r (n,) whose errors may be correlated within each cluster of
    ``labels`` but not between them (Liang and Zeger, 1986), in the form that equals a
    delete-one-cluster jackknife to first order ("CR3", Bell and McCaffrey, 2002): each
    cluster's residuals are first divided by (I - its block of the hat matrix), since
    the fit has pulled itself towards them. The residuals are also smaller than the
    errors by the ``eliminated`` parameters solved for inside (a depth per track): the
    n / (n - eliminated) factor. On tracks with shimmer-like noise this matched the
    spread of the fit over 40 draws (0.33 against 0.32 px at the corner; taking the
    residuals as independent gave 0.19 px). Each cluster's solve (LAPACK, one BLAS
    thread) is a task of a :class:`rigkit.core.threads.ViewPool`, taken in the clusters'
    order: the same covariance bit for bit on any number of threads."""
    bread = np.linalg.inv(J.T @ J)

    def score(c: int) -> np.ndarray:
        Jc, rc = J[labels == c], r[labels == c]
        leverage = Jc @ bread @ Jc.T
        return Jc.T @ np.linalg.solve(np.eye(len(rc)) - leverage, rc)

    with ViewPool() as pool:
        scores = pool.map(score, np.unique(labels))
    g, n = len(scores), len(r)
    meat = np.einsum("ci,cj->ij", scores, scores) * (g - 1) / g * n / max(n - eliminated, 1)
    return bread @ meat @ bread
