"""Finding the maximum-likelihood optimum over (θ, β) or θ: bounded L-BFGS-B from several starts with central
finite-difference gradients, restarted from the best point until it stops improving, and never stuck at a zero
variance that a small one beats.

Central differences: the deviance is exact only to its rounding (~1e-13 relative), which forward differences
(step ~1e-8) turn into gradient noise of order 1e-2 on a deviance of ~1e3, enough to stall a line search far
from the optimum (seen on a Poisson GLMM with three scenes, 0.12 log-likelihood short). Restarts: L-BFGS-B can
stop on "no further reduction" with a poor curvature model; a fresh start from its end point moves on.

The deviance of a mixed model is even in each relative standard deviation θ_k (it depends on θ_k²), so θ_k = 0
is a stationary point: a gradient method whose step overshoots onto that bound finds a zero projected gradient
there and stops, even when the deviance is lower at a small positive θ_k. lme4's derivative-free BOBYQA does not
stop there. After the gradient fits, :func:`off_zero` scans small values of every component at zero, and the fit
restarts from a point that is better.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from scipy import optimize

SCAN = (0.3, 0.1, 0.03, 0.01, 0.003)  # the θ tried for a component at zero
AT_ZERO = 1e-3


def off_zero(deviance: Callable[[np.ndarray], float], best: optimize.OptimizeResult,
             zero_bounded: list[int]) -> np.ndarray | None:
    """The best point that beats ``best`` with one of its ``zero_bounded`` components at zero set to a small
    value of :data:`SCAN`, or None."""
    found, value = None, best.fun
    for i in zero_bounded:
        if abs(best.x[i]) >= AT_ZERO:
            continue
        for small in SCAN:
            x = best.x.copy()
            x[i] = small
            f = deviance(x)
            if f < value:
                found, value = x, f
    return found


def minimize(deviance: Callable[[np.ndarray], float], starts: list[np.ndarray], bounds: list,
             zero_bounded: list[int], before: Callable[[], None] = lambda: None) -> optimize.OptimizeResult:
    """The best optimum from ``starts`` (``before`` runs before each fit, e.g. to reset warm starts), restarted —
    from a scanned point off zero where one beats it, else from itself — until no restart improves it by more
    than 1e-10."""
    options = {"ftol": 1e-15, "gtol": 1e-9, "maxiter": 2000}

    def fit(x):
        before()
        return optimize.minimize(deviance, x, method="L-BFGS-B", jac="3-point", bounds=bounds, options=options)

    best = min((fit(x) for x in starts), key=lambda r: r.fun)
    for _ in range(10):
        start = off_zero(deviance, best, zero_bounded)
        again = fit(best.x if start is None else start)
        if not again.fun < best.fun - 1e-10:
            return again if again.fun < best.fun else best
        best = again
    return best
