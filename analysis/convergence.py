"""Whether a fit is singular, and whether it converged, checked as lme4 checks them (``lme4:::checkConv``, with
``lmerControl()``'s and ``glmerControl()``'s defaults), with lme4's words.

- Singular (``check.conv.singular``, tolerance 1e-4): a diagonal entry of a relative covariance factor below the
  tolerance — a variance at zero, or a correlation at ±1. lme4 then says "boundary (singular) fit: see
  help('isSingular')" and checks nothing else.
- Otherwise the scaled gradient (``check.conv.grad``, tolerance 2e-3): with g the deviance's gradient at the optimum
  and H its Hessian, the largest of min(|H⁻¹ᐟ²g|, |g|) (lme4 solves with chol(H)) must not exceed the tolerance.
- And the Hessian (``check.conv.hess``, tolerance 1e-6): negative eigenvalues (not a minimum), eigenvalues at zero
  (parameters not determined), a very large eigenvalue or a large eigenvalue ratio; for a GLMM its fixed-effect
  block first.

The messages are lme4's to the character (its "component 1" whichever component it is, its line breaks and spaces).
lme4 computes g and H by finite differences of the deviance (``deriv12``, step 1e-4); the linear mixed model and the
Poisson GLMM by Laplace have the exact gradient, and their Hessian is the central difference of that
(:mod:`analysis.lmm`, :mod:`analysis.glmm`); a Poisson GLMM by quadrature takes lme4's own. A fit run to
convergence, as these are, rarely fails the gradient check; the check says so when it does.
"""

from __future__ import annotations

import numpy as np

SINGULAR_TOL = 1e-4  # check.conv.singular
GRADIENT_TOL = 2e-3  # check.conv.grad
HESSIAN_TOL = 1e-6  # check.conv.hess
SINGULAR = "boundary (singular) fit: see help('isSingular')"


def is_singular(theta: np.ndarray, diagonal: np.ndarray) -> bool:
    """lme4's ``isSingular``: a diagonal entry of a relative covariance factor (``diagonal`` marks them in θ) below
    SINGULAR_TOL."""
    return bool(np.any(np.abs(np.asarray(theta)[diagonal]) < SINGULAR_TOL))


def gradient_hessian(gradient, x: np.ndarray, step: float) -> np.ndarray:
    """The Hessian at ``x`` as central differences of step ``step`` of an exact ``gradient`` (a function of the
    parameters), symmetrised: 2n gradients where differences of the deviance take ~2n² values."""
    hessian = np.empty((len(x), len(x)))
    for i, e in enumerate(np.eye(len(x)) * step):
        hessian[i] = (gradient(x + e) - gradient(x - e)) / (2 * step)
    return (hessian + hessian.T) / 2


def messages(theta: np.ndarray, diagonal: np.ndarray, gradient=None, hessian=None) -> list[str]:
    """lme4's convergence messages for a fit at θ (``gradient`` and ``hessian``: the deviance's over the optimised
    parameters, θ first; computed by the caller only when the fit is not singular — None skips those checks)."""
    if is_singular(theta, diagonal):
        return [SINGULAR]
    out = []
    if gradient is not None and hessian is not None:
        gradient, hessian = np.asarray(gradient, float), np.asarray(hessian, float)
        if np.any(np.isnan(gradient)):
            return ["Gradient contains NAs"]
        try:
            scaled = np.linalg.solve(np.linalg.cholesky(hessian).T, gradient)
        except np.linalg.LinAlgError:
            scaled = None
        if scaled is None or np.any(~np.isfinite(scaled)):
            out.append("unable to evaluate scaled gradient")
        else:
            smallest = np.minimum(np.abs(scaled), np.abs(gradient))
            if smallest.max() > GRADIENT_TOL:
                # lme4 names "component 1" whichever component it is (which.max of the maximum); so does this,
                # to say what lme4 says
                out.append(f"Model failed to converge with max|grad| = {smallest.max():.6g} "
                           f"(tol = {GRADIENT_TOL:g}, component 1)")
        k = len(theta)
        if len(gradient) > k:
            out += _hessian_messages(hessian[k:, k:], "fixed-effect")
        out += _hessian_messages(hessian)
    return out


def _hessian_messages(hessian: np.ndarray, kind: str = "") -> list[str]:
    """``lme4:::checkHess``."""
    try:
        values = np.linalg.eigvalsh(hessian)
    except np.linalg.LinAlgError:
        return ["Problem with Hessian check (infinite or missing values?)"]
    negative = int((values < -HESSIAN_TOL).sum())
    if negative:
        return [f"Model failed to converge: degenerate {kind} Hessian with {negative} negative eigenvalues"]
    try:
        np.linalg.cholesky(hessian)
        positive = True
    except np.linalg.LinAlgError:
        positive = False
    if np.any(np.abs(values) < HESSIAN_TOL) or not positive:
        return [f"{kind} Hessian is numerically singular: parameters are not uniquely determined"]
    out = []
    if values.max() * HESSIAN_TOL > 1:
        out.append("Model is nearly unidentifiable: very large eigenvalue\n - Rescale variables?")
    if values.min() / values.max() < HESSIAN_TOL:
        out.append("Model is nearly unidentifiable: large eigenvalue ratio\n - Rescale variables?")
    return out


def failed(messages: list[str] | tuple[str, ...]) -> bool:
    """Whether lme4's messages say the fit did not converge (not only that it is singular or badly scaled)."""
    return any(m.startswith(("Model failed to converge", "unable to evaluate scaled gradient",
                             "Gradient contains NAs")) for m in messages)
