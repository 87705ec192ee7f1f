"""Finding the maximum-likelihood optimum over (θ, β) or θ: from several starts, restarted from the best point
until it stops improving, and never stuck at a zero variance that a small one beats. Each local fit is BOBYQA,
or L-BFGS-B where the deviance's exact gradient is known (the linear mixed model, :mod:`analysis.lmm`, and the
Poisson GLMM by Laplace, :mod:`analysis.glmm`).

BOBYQA (Powell 2009; NLopt's implementation) is the derivative-free, bound-constrained trust-region method lme4
optimises with (lmer's default ``nloptwrap`` is NLopt's BOBYQA; glmer's second stage minqa's): it builds a
quadratic model of the deviance from its values, so the deviance's rounding (~1e-13 relative) never turns into
gradient noise, and on a model with random slopes (12 θ) it converges in a few hundred deviance evaluations where
bounded L-BFGS-B with finite-difference gradients took ~9,000. It is run far tighter than lme4's defaults (which
stop where a flat likelihood leaves a variance ~1% off): to a trust region of XTOL.

Restarts: a trust-region method can stop with a poor quadratic model; a fresh start from its end point moves on.
The deviance of a mixed model is even in each relative standard deviation θ_k of an intercept-only term (it depends
on θ_k²), so θ_k = 0 is a stationary point where a local method can stop although the deviance is lower at a small
positive θ_k. After the fits, :func:`off_zero` scans small values of every component at zero, and the fit restarts
from a point that is better. With random slopes a factor's column can sit at zero where the better optimum lies
off it only once the rest of the column is turned over or rotated (the deviance depends on a factor T only through
TT'): local fits start from those turns too (:meth:`analysis.random_effects.RandomEffects.ways_off_zero`).
"""

from __future__ import annotations

from collections.abc import Callable, Iterable

import nlopt
import numpy as np
from scipy import optimize

SCAN = (0.3, 0.1, 0.03, 0.01, 0.003)  # the θ tried for a component at zero
AT_ZERO = 1e-3
XTOL = 1e-11  # the final trust-region radius, in the parameters' units
MAX_EVALUATIONS = 100_000
IMPROVES = 1e-10  # a restart must lower the deviance by more than this to count
TURN = 0.01  # the diagonal θ a local fit starts from after a column at zero is turned (see minimize)
#: The first trust region, as a fraction of each parameter's scale: from a start, lme4's (a fifth); from an optimum
#: already found, a hundredth (a restart only has to rebuild the quadratic model where it is)
START_STEP, RESTART_STEP = 0.2, 0.01


def off_zero(deviance: Callable[[np.ndarray], float], best: optimize.OptimizeResult,
             escapes: Callable[..., Iterable[np.ndarray]]) -> np.ndarray | None:
    """The best point that beats ``best`` among the ways off zero ``escapes(best.x)`` gives (each variance at zero
    set to a small value of :data:`SCAN`, and the turns of its column:
    :meth:`analysis.random_effects.RandomEffects.ways_off_zero`); None when none is better."""
    found, value = None, best.fun
    for x in escapes(best.x):
        f = deviance(x)
        if f < value:
            found, value = x, f
    return found


def bobyqa(deviance: Callable[[np.ndarray], float], x0: np.ndarray, bounds: list,
           step: float = 0.2) -> optimize.OptimizeResult:
    """One BOBYQA run from ``x0`` within ``bounds`` ((low, high) per parameter, None for none), first trust region
    ``step`` times each parameter's size (a size below 0.25 counting as 0.25), last XTOL; the best point it
    evaluated (NLopt can stop on rounding before it reports one)."""
    x0 = np.asarray(x0, dtype=float)
    low = np.array([-np.inf if lo is None else lo for lo, _ in bounds])
    high = np.array([np.inf if hi is None else hi for _, hi in bounds])
    x0 = np.clip(x0, low, high)
    best = {"x": x0, "fun": np.inf, "nfev": 0}

    def objective(x, _grad):
        value = float(deviance(x))
        best["nfev"] += 1
        if value < best["fun"]:
            best["x"], best["fun"] = np.array(x), value
        return value if np.isfinite(value) else 1e300

    opt = nlopt.opt(nlopt.LN_BOBYQA, len(x0))
    opt.set_lower_bounds(low)
    opt.set_upper_bounds(high)
    opt.set_min_objective(objective)
    opt.set_xtol_abs(XTOL)
    opt.set_maxeval(MAX_EVALUATIONS)
    opt.set_initial_step(step * np.maximum(np.abs(x0), 0.25))
    try:
        opt.optimize(x0)
        status = opt.last_optimize_result()
    except nlopt.RoundoffLimited:  # the best point is as good as rounding allows
        status = nlopt.ROUNDOFF_LIMITED
    return optimize.OptimizeResult(x=best["x"], fun=best["fun"], nfev=best["nfev"], status=status,
                                   success=status > 0 or status == nlopt.ROUNDOFF_LIMITED)


class _NoGradient(ArithmeticError):
    """The gradient is not a finite number here (a residual variance at zero: the deviance falls without bound)."""


def gradient_descent(with_gradient: Callable[[np.ndarray], tuple[float, np.ndarray]], x0: np.ndarray,
                     bounds: list) -> optimize.OptimizeResult:
    """Bounded L-BFGS-B on a deviance with its exact gradient (``with_gradient`` returns both), run until its
    line search can no longer lower the deviance; raises _NoGradient where the gradient is not finite."""

    def checked(x):
        value, gradient = with_gradient(x)
        if not (np.all(np.isfinite(gradient)) and np.all(np.isfinite(x))):
            raise _NoGradient
        return value, gradient

    return optimize.minimize(checked, x0, jac=True, method="L-BFGS-B", bounds=bounds,
                             options={"ftol": 1e-15, "gtol": 1e-10, "maxiter": 5000, "maxcor": 20})


def minimize(deviance: Callable[[np.ndarray], float], starts: list[np.ndarray], bounds: list,
             escapes: Callable[..., Iterable[np.ndarray]], before: Callable[[], None] = lambda: None,
             with_gradient: Callable[[np.ndarray], tuple[float, np.ndarray]] | None = None
             ) -> optimize.OptimizeResult:
    """The best optimum from ``starts`` (``before`` runs before each fit, e.g. to reset warm starts), restarted —
    from a scanned point off zero where one beats it, else from itself — until no restart improves it by more
    than IMPROVES. Each local fit is BOBYQA on ``deviance``, or, where the deviance has an exact gradient
    (``with_gradient``: the linear mixed model's, the Poisson GLMM's by Laplace), L-BFGS-B on it: a few dozen
    evaluations instead of hundreds (BOBYQA again from a start where that gradient is not finite). ``escapes``:
    see :func:`off_zero`; where none of its points is better at once, a local fit starts from each of its turned
    columns (``escapes(x, (TURN,), plain=False)``) too."""

    def fit(x, step=START_STEP):
        before()
        if with_gradient is not None:
            try:
                return gradient_descent(with_gradient, x, bounds)
            except _NoGradient:
                pass  # BOBYQA needs no gradient
        return bobyqa(deviance, x, bounds, step)

    best = min((fit(x) for x in starts), key=lambda r: r.fun)
    for _ in range(10):
        start = off_zero(deviance, best, escapes)
        again = fit(best.x, RESTART_STEP) if start is None else fit(start)
        if not again.fun < best.fun - IMPROVES:
            # where no point off zero is better at once, the way to a better optimum can still lead off it: a local
            # fit from each turn of a column at zero (a random study's Poisson model: 5e-5 of log-likelihood)
            again = min([again, *(fit(x) for x in escapes(best.x, (TURN,), plain=False))], key=lambda r: r.fun)
        if not again.fun < best.fun - IMPROVES:
            return again if again.fun < best.fun else best
        best = again
    return best
