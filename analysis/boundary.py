"""Leaving a variance at zero when a small one fits better.

The deviance of a mixed model is even in each relative standard deviation θ_k (it depends on θ_k²), so θ_k = 0
is a stationary point: a gradient method whose step overshoots onto that bound finds a zero projected gradient
there and stops, even when the deviance is lower at a small positive θ_k. lme4's derivative-free BOBYQA does not
stop there. After the gradient fits, :func:`escape_zero` scans small values of every component at zero and
restarts the fit from any point that is better, until none is.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from scipy import optimize

SCAN = (0.3, 0.1, 0.03, 0.01, 0.003)  # the θ tried for a component at zero
AT_ZERO = 1e-3


def escape_zero(deviance: Callable[[np.ndarray], float], best: optimize.OptimizeResult, zero_bounded: list[int],
                bounds: list, options: dict | None = None) -> optimize.OptimizeResult:
    """``best`` (an L-BFGS-B result over ``bounds``), or a better one restarted from a scanned point where a
    component listed in ``zero_bounded`` was at zero."""
    for _ in range(len(zero_bounded) + 1):
        trials = []
        for i in zero_bounded:
            if abs(best.x[i]) >= AT_ZERO:
                continue
            for value in SCAN:
                x = best.x.copy()
                x[i] = value
                trials.append((deviance(x), x))
        better = [(f, x) for f, x in trials if f < best.fun]
        if not better:
            return best
        start = min(better, key=lambda fx: fx[0])[1]
        again = optimize.minimize(deviance, start, method="L-BFGS-B", bounds=bounds, options=options)
        if not again.fun < best.fun:
            return best
        best = again
    return best
