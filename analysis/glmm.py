"""Poisson mixed models (log link; random intercepts and slopes) by maximum likelihood, as lme4's ``glmer`` fits
them.

statsmodels has no maximum-likelihood GLMM, so the likelihood is written here in lme4's terms: spherical random
effects u ~ N(0, I), b = Λ_θ u (:mod:`analysis.random_effects`); for given (θ, β) penalised iteratively
reweighted least squares finds the conditional mode û and the Laplace approximation is

    −2 ℓ ≈ −2 Σ log Pois(y | μ(û)) + ‖û‖² + log det(Λ'Z'WZΛ + I),   W = diag(μ).

With a single random intercept ``n_agq > 1`` replaces it by adaptive Gauss–Hermite quadrature around û. (θ, β)
are optimised together, as lme4's second stage does: the Laplace deviance has an exact gradient (implicit
differentiation through û: :meth:`_Laplace.deviance_and_gradient`), so each local fit is L-BFGS-B in a few dozen
evaluations, from two starts (five with random slopes, whose likelihood can have several optima), the best
restarted (:mod:`analysis.optimum`); quadrature takes BOBYQA. Standard errors come from the Hessian of −2 ℓ over
(θ, β), lme4's default: central differences of the exact gradient (of the deviance, as lme4's ``deriv12``, with
quadrature).

Why glmer's numbers differ slightly from these (its default SEs by 0.3–0.6% on the reference data; on 30 random
studies by up to 1.4%, estimates by up to 0.3% of an SE, logLik by up to 9e-4; on one study with small counts its
default vcov gave SEs of 0.003 where the converged value is 0.19): glmer's deviance function runs PIRLS from a
fixed start (the first stage's linear predictor), stops when the penalised deviance changes by less than
``tolPwrss`` (relative; 1e-7 by default) and evaluates the log-determinant at the weights of the start of its last
iteration. The penalised deviance is stationary in u, so it stops while those weights are still off by the first
order of the last step, and the log-determinant is first-order in them: an error of ~1e-7–1e-6 in the deviance,
smooth in (θ, β), which the finite-difference Hessian (step 1e-4) takes in 1e8 times over and the optimum and
logLik carry too. (Emulating that PIRLS reproduces glmer's deviance to 1e-12.) Tightening the optimizer moves its
SEs by ~1e-6; tightening ``tolPwrss`` to 1e-13 converges some studies (the reference data: SEs then agree with
these to ~5e-6) but not all (0.5% left on one random study; at 1e-15 and below its PIRLS turns noisy or fails).
Restarting glmer's own deviance function from its last linear predictor until its value stops changing gives the
converged Laplace deviance — equal to this module's to ~1e-11; its optimum (BOBYQA on it, from glmer's fit) and
lme4's deriv12 there give estimates, logLik and SEs equal to these within 1e-4 (glmer's own optimum can be 3e-4 of
an SE away). We match those converged values; the lme4 oracle test (tests/test_lme4_oracle.py, tests/lme4_oracle.R)
re-checks that on random studies in every CI run.
"""

from __future__ import annotations

import numpy as np
from scipy.special import gammaln
from statsmodels.genmod.families import Poisson
from statsmodels.genmod.generalized_linear_model import GLM

from .convergence import gradient_hessian, is_singular, messages
from .design import Design, formula_of
from .errors import AnalysisError
from .lmm import components
from .optimum import minimize
from .random_effects import Curvature, RandomEffects, term_factors
from .results import MixedFit

STEP = 1e-4  # finite-difference step of the Hessian (lme4's deriv12)
NEAR = 1e-8  # Newton decrement g'H⁻¹g below which PIRLS takes full steps (its quadratic region)
DONE = 1e-14  # PIRLS stops after a step this small (largest |Δu|)
WILD = 1e300  # deviance reported where the likelihood overflows, so line searches back off
START_THETA = (1.0, 0.2)  # multi-start: lme4's θ = 1 and a small-variance start
#: With random slopes the likelihood has more than one optimum (on a random study, θ = 1, 0.2 and 0.1 times the
#: identity end 0.27 log-likelihood below where 0.5 does): more starts, each cheap with the exact gradient
START_THETA_SLOPES = (1.0, 0.5, 0.2, 2.0, 0.1)


class _Laplace:
    """−2 log-likelihood of a Poisson GLMM as a function of (θ, β), warm-starting the conditional modes."""

    def __init__(self, design: Design, n_agq: int):
        self.y, self.X = design.y, design.X
        self.z = RandomEffects(design.random)
        self.k, self.p, self.q = self.z.n_theta, design.X.shape[1], self.z.q
        self.n_agq = n_agq
        self.codes = design.random[0].codes
        self.nodes, self.weights = np.polynomial.hermite.hermgauss(n_agq)
        self.const = gammaln(self.y + 1).sum()
        self.u = np.zeros(self.q)

    def _h(self, theta, mu) -> Curvature:
        """Λ'Z'WZΛ + I with W = diag(μ)."""
        return self.z.curvature(theta, self.z.crosstabs(mu))

    def _mode(self, theta, beta, u):
        """PIRLS for û given (θ, β) — û, η, Z'WZ by blocks (:meth:`RandomEffects.crosstabs`) and H at û: Newton steps on
        Σ(yη − μ) − ‖u‖²/2, halved while far from the mode, full in its quadratic region (Newton decrement below
        ``NEAR``) until a step is below ``DONE``. The stop rule is the step, not the objective's change: near
        the mode that change is below the objective's rounding (~1e-12) while û can still be ~1e-8 off, and the
        log-determinant is first-order in û, so a finite-difference Hessian (step 1e-4) would take such an error
        in 1e8 times over."""
        eta0 = self.X @ beta

        def objective(u):
            eta = eta0 + self.z.zl_u(theta, u)
            return float(self.y @ eta - np.exp(eta).sum() - u @ u / 2)

        current = objective(u)
        if not np.isfinite(current):  # a warm start from a wild evaluation: start from the prior mean
            u = np.zeros(self.q)
            current = objective(u)
        for _ in range(100):
            mu = np.exp(eta0 + self.z.zl_u(theta, u))
            g = self.z.zl_t(theta, self.y - mu) - u
            delta = self._h(theta, mu).solve(g)
            if g @ delta < NEAR:  # quadratic convergence from here: full steps
                u = u + delta
                if np.abs(delta).max() < DONE:
                    break
                current = objective(u)
                continue
            step, trial = 1.0, -np.inf
            while step > 1e-10:
                trial = objective(u + step * delta)
                if trial >= current - 1e-12:
                    break
                step /= 2
            if not trial >= current - 1e-12:
                break  # no step improves: û is as good as it gets
            u, current = u + step * delta, trial
        eta = eta0 + self.z.zl_u(theta, u)
        tabs = self.z.crosstabs(np.exp(eta))
        return u, eta, tabs, self.z.curvature(theta, tabs)

    def deviance(self, params: np.ndarray) -> float:
        theta, beta = params[:self.k], params[self.k:]  # a negative diagonal θ is a valid factor too
        try:
            with np.errstate(over="ignore", invalid="ignore"):
                u, eta, _, h = self._mode(theta, beta, self.u)
        except (np.linalg.LinAlgError, ValueError):
            return WILD
        if not (np.all(np.isfinite(u)) and np.all(np.isfinite(h.d_inv))):
            return WILD
        self.u = u
        if self.n_agq == 1:
            loglik = self.y @ eta - np.exp(eta).sum() - self.const - u @ u / 2
            try:
                return float(-2 * loglik + h.logdet())
            except np.linalg.LinAlgError:
                return WILD
        return float(-2 * self._agq(theta[0], beta, u, h.d[:, 0, 0]))

    def deviance_and_gradient(self, params: np.ndarray) -> tuple[float, np.ndarray]:
        """The Laplace deviance and its exact gradient in (θ, β). û solves Λ'Z'(y − μ) = u, so it moves with (θ, β)
        by H⁻¹ times that equation's derivative (implicit differentiation), and the log-determinant moves with û
        through W = diag(μ). With h the diagonal of ZΛH⁻¹Λ'Z' (:meth:`RandomEffects.leverages`), s = μ∘h,
        w = H⁻¹Λ'Z's and ρ = s − 2(y − μ) − μ∘(ZΛw), for θ_i an entry (r, c) of a factor's T (Λ_i = ∂Λ/∂θ_i):

            ∂D/∂β = X'ρ,   ∂D/∂θ_i = (Z'ρ)'Λ_i û + (Z'(y − μ))'Λ_i w + 2 tr(H⁻¹Λ'Z'WZ Λ_i),

        each of the θ terms a sum over the levels of θ_i's factor of per-level blocks (as the linear mixed model's
        gradient, :meth:`analysis.lmm._Profiled.deviance_and_gradient`). The Laplace approximation only: with
        quadrature the gradient is not this."""
        params = np.asarray(params, dtype=float)
        theta, beta = params[:self.k], params[self.k:]
        try:
            with np.errstate(over="ignore", invalid="ignore"):
                u, eta, tabs, h = self._mode(theta, beta, self.u)
                mu = np.exp(eta)
                if not (np.all(np.isfinite(u)) and np.all(np.isfinite(mu))):
                    raise ValueError("overflow")
                dev = float(-2 * (self.y @ eta - mu.sum() - self.const) + u @ u + h.logdet())
                effects = self.z
                s = mu * effects.leverages(theta, h)
                w = h.solve(effects.zl_t(theta, s))
                rho = s - 2 * (self.y - mu) - mu * effects.zl_u(theta, w)
                h00, h_rest = h.inverse_times_diagonal(*effects.lam_t_ztz(theta, tabs))
        except (np.linalg.LinAlgError, ValueError):  # overflow: a line search backs off from a value this large
            return WILD, np.zeros_like(params)
        self.u = u
        grad = np.empty_like(params)
        grad[self.k:] = self.X.T @ rho
        levels = zip(effects.groups, effects.level_blocks(effects.zt(rho)),
                     effects.level_blocks(effects.zt(self.y - mu)), effects.level_blocks(u), effects.level_blocks(w),
                     strict=True)
        for k, (g, z_rho, z_res, u_g, w_g) in enumerate(levels):
            trace = h00 if k == 0 else effects.rest_diagonal(h_rest, k)
            grad[g.theta] = ((z_rho[:, g.rows] * u_g[:, g.cols]).sum(axis=0)
                             + (z_res[:, g.rows] * w_g[:, g.cols]).sum(axis=0)
                             + 2 * trace[:, g.cols, g.rows].sum(axis=0))
        return dev, grad

    def _agq(self, theta, beta, u, h) -> float:
        """Σ over groups of log ∫ Π_i Pois(y_i | b) N(b; 0, θ²) db by Gauss–Hermite around the mode."""
        eta0 = self.X @ beta
        scale = np.sqrt(2.0 / h)
        terms = []
        for z in self.nodes:
            v = u + scale * z
            eta = eta0 + theta * v[self.codes]
            f = np.bincount(self.codes, self.y * eta - np.exp(eta), minlength=len(u)) - v * v / 2
            terms.append(f + z * z)
        terms = np.array(terms)
        top = terms.max(axis=0)
        log_sum = top + np.log(self.weights @ np.exp(terms - top))
        return float((log_sum + np.log(scale) - 0.5 * np.log(2 * np.pi)).sum() - self.const)


def _derivatives(f, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The gradient and Hessian of ``f`` at ``x`` by central differences of step STEP (lme4's ``deriv12``)."""
    n = len(x)
    h, g = np.empty((n, n)), np.empty(n)
    f0 = f(x)
    for i in range(n):
        for j in range(i, n):
            ei, ej = np.eye(n)[i] * STEP, np.eye(n)[j] * STEP
            if i == j:
                plus, minus = f(x + ei), f(x - ei)
                h[i, i] = (plus - 2 * f0 + minus) / STEP**2
                g[i] = (plus - minus) / (2 * STEP)
            else:
                h[i, j] = h[j, i] = (f(x + ei + ej) - f(x + ei - ej) - f(x - ei + ej) + f(x - ei - ej)) / (4 * STEP**2)
    return g, h


def fit_poisson(design: Design, n_agq: int = 1) -> MixedFit:
    """Poisson GLMM; ``loglik`` is the Laplace (or quadrature) log-likelihood."""
    y = design.y
    if np.any(y < 0) or np.any(y != np.round(y)):
        raise AnalysisError("a Poisson model needs counts (whole numbers ≥ 0)", f"response {design.response!r}")
    if n_agq > 1 and len(design.random) > 1:
        raise AnalysisError("adaptive quadrature needs a single random intercept (as lme4's nAGQ > 1); use the "
                            "Laplace approximation", "--random")
    if y.sum() == 0:
        raise AnalysisError("is zero everywhere; there is nothing to model", f"response {design.response!r}")
    model = _Laplace(design, n_agq)
    beta0 = GLM(y, design.X, family=Poisson()).fit().params
    k = model.k
    bounds = [(0, None) if diagonal else (None, None) for diagonal in model.z.diagonal] + [(None, None)] * model.p
    slopes = any(t.values is not None for t in design.random)
    starts = [np.concatenate([np.where(model.z.diagonal, theta, 0.0), beta0])
              for theta in (START_THETA_SLOPES if slopes else START_THETA)]

    def reset():
        model.u = np.zeros(model.q)

    laplace = n_agq == 1
    best = minimize(model.deviance, starts, bounds, model.z.ways_off_zero, before=reset,
                    with_gradient=model.deviance_and_gradient if laplace else None)
    if not best.fun < WILD:
        raise AnalysisError("the likelihood could not be evaluated anywhere the optimiser looked",
                            f"response {design.response!r}")
    x = best.x
    dev = model.deviance(x)
    grad, hess = None, None
    if laplace:
        grad = model.deviance_and_gradient(x)[1]
        hess = gradient_hessian(lambda v: model.deviance_and_gradient(v)[1], x, STEP)
    if hess is None or not (np.all(np.isfinite(hess)) and np.all(np.isfinite(grad))):
        grad, hess = _derivatives(model.deviance, x)  # quadrature, or a gradient not finite next to the optimum
    try:
        cov = 2 * np.linalg.inv(hess)[k:, k:]
    except np.linalg.LinAlgError:
        cov = np.full((model.p, model.p), np.nan)
    if not np.all(np.isfinite(np.diag(cov))) or np.any(np.diag(cov) <= 0):
        # A boundary θ makes the Hessian indefinite; fall back on the fixed-effects block alone.
        cov = 2 * np.linalg.pinv(hess[k:, k:])
    theta = x[:k]
    se = np.sqrt(np.clip(np.diag(cov), 0, None))
    return MixedFit(
        family="poisson", formula=formula_of(design), nobs=design.nobs,
        groups={t.group: len(t.levels) for t in design.random},
        fixed=dict(zip(design.fixed_names, map(float, x[k:]), strict=True)),
        se=dict(zip(design.fixed_names, map(float, se), strict=True)), cov_fixed=cov,
        variance=components(design.random, term_factors(design.random, theta), 1.0),
        loglik=-dev / 2, n_params=model.p + k, optimizer="L-BFGS-B (exact gradient)" if laplace else "bobyqa",
        singular=is_singular(theta, model.z.diagonal),
        messages=tuple(messages(theta, model.z.diagonal, grad, hess)), theta=tuple(map(float, theta)),
        dropped=design.dropped, extra={"n_agq": n_agq})
