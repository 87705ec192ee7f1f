"""Linear mixed models by maximum likelihood (or REML), computed as lme4 computes them.

lme4's profiled deviance (Bates, Mächler, Bolker & Walker 2015, §3): random effects b = Λ_θ u with spherical u;
for given θ the fixed effects and σ² have closed forms, so the optimiser only searches θ (one relative standard
deviation per random intercept; the lower triangle of a term's covariance factor for correlated slopes).
Everything is computed from the cross-products Z'Z, Z'X, Z'y, X'X, X'y, y'y, so an evaluation costs one
factorisation of the curvature whatever the number of rows: small blocks per participant and the Schur complement
over the other factors (:mod:`analysis.random_effects`).

statsmodels' MixedLM gives the same estimates (crossed factors as variance components of one group) but takes
~20 s per fit on 1800 rows with 200 participants, because it works on the dense n×q design of that one group;
this formulation takes well under a second, which is what keeps the report's budget.

The deviance's exact gradient in θ is computed from the same blocks (:meth:`_Profiled.deviance_and_gradient`), so
each local fit is L-BFGS-B with it: a few dozen evaluations where lme4's derivative-free BOBYQA takes hundreds.
The flat likelihood in a variance near zero can stop one optimiser early, so each fit is multi-start (θ = 1, 0.1
and 3 times the identity, the best restarted and moved off zero variances by :mod:`analysis.optimum`).
Fixed-effect covariances are lme4's σ² (X'V⁻¹X)⁻¹.
"""

from __future__ import annotations

import numpy as np
from scipy.linalg import block_diag, cho_factor, cho_solve, solve_triangular

from .convergence import gradient_hessian, is_singular, messages
from .design import Design, formula_of
from .errors import AnalysisError
from .optimum import minimize
from .random_effects import RandomEffects, term_factors
from .results import MixedFit

STARTS = (1.0, 0.1, 3.0)
ROUNDING = 1e-12  # a penalised residual sum of squares below this share of y'y is rounding


class _Profiled:
    """−2 log-likelihood (or the REML criterion) as a function of θ alone."""

    def __init__(self, design: Design, reml: bool, blocked: bool = True):
        """``blocked``: solve through the block structure of :mod:`analysis.random_effects` (False: a dense q×q
        Cholesky, kept for tests that compare the two)."""
        self.design, self.reml = design, reml
        X, y = design.X, design.y
        self.n, self.p = X.shape
        self.xtx, self.xty, self.yty = X.T @ X, X.T @ y, float(y @ y)
        self.effects = RandomEffects(design.random)
        if blocked:
            self.tabs = self.effects.crosstabs(np.ones(self.n))
            self.zt_yx = self.effects.zt(np.column_stack([y, X]))
        else:
            self.tabs = None
            Z = design.z()
            self.ztz = (Z.T @ Z).toarray()
            self.ztx = np.asarray(Z.T @ X)
            self.zty = np.asarray(Z.T @ y)
        self.q = self.effects.q
        self.bounds = [(0, None) if diagonal else (None, None) for diagonal in self.effects.diagonal]

    def blocks(self, theta: np.ndarray) -> list[np.ndarray]:
        return term_factors(self.design.random, theta)

    def lam(self, theta: np.ndarray) -> np.ndarray:
        parts = [np.kron(np.eye(len(t.levels)), b) for t, b in zip(self.design.random, self.blocks(theta),
                                                                    strict=True)]
        return block_diag(*parts)

    def _products(self, theta: np.ndarray) -> tuple[float, np.ndarray, np.ndarray, float]:
        """With A = Λ'Z'ZΛ + I = LL': ‖L⁻¹Λ'Z'y‖², (L⁻¹Λ'Z'X)'(L⁻¹Λ'Z'y), (L⁻¹Λ'Z'X)'(L⁻¹Λ'Z'X) and log det A."""
        if self.tabs is not None:
            theta = np.asarray(theta, dtype=float)
            a = self.effects.curvature(theta, self.tabs)
            b = self.effects.scale_t(theta, self.zt_yx)  # Λ'Z'[y X]
            s = a.solve(b)
            return float(b[:, 0] @ s[:, 0]), b[:, 1:].T @ s[:, 0], b[:, 1:].T @ s[:, 1:], a.logdet()
        lam = self.lam(theta)
        chol = np.linalg.cholesky(lam.T @ self.ztz @ lam + np.eye(self.q))
        cu = solve_triangular(chol, lam.T @ self.zty, lower=True)
        rzx = solve_triangular(chol, lam.T @ self.ztx, lower=True)
        return float(cu @ cu), rzx.T @ cu, rzx.T @ rzx, 2 * float(np.log(np.diag(chol)).sum())

    def solve(self, theta: np.ndarray) -> dict:
        return self._profile(*self._products(theta))

    def _profile(self, cu_cu: float, rzx_cu: np.ndarray, rzx_rzx: np.ndarray, logdet_l: float) -> dict:
        """The deviance (or REML criterion), β̂, σ², X'V⁻¹X (scaled), its Cholesky factor and the penalised residual
        sum of squares r², from :meth:`_products`."""
        xvx = self.xtx - rzx_rzx
        rx = np.linalg.cholesky(xvx)
        cb = solve_triangular(rx, self.xty - rzx_cu, lower=True)
        r2 = self.yty - cu_cu - cb @ cb
        floored = max(r2, 1e-300)
        dof = self.n - self.p if self.reml else self.n
        dev = logdet_l + dof * (1 + np.log(2 * np.pi * floored / dof))
        if self.reml:
            dev += 2 * np.log(np.diag(rx)).sum()
        beta = solve_triangular(rx.T, cb, lower=False)
        return {"deviance": float(dev), "beta": beta, "sigma2": floored / dof, "xvx": xvx, "rx": rx, "r2": r2,
                "dof": dof}

    def deviance(self, theta: np.ndarray) -> float:
        try:
            return self.solve(theta)["deviance"]
        except (np.linalg.LinAlgError, ValueError):  # not positive definite, or θ not finite
            return 1e300

    def deviance_and_gradient(self, theta: np.ndarray) -> tuple[float, np.ndarray]:
        """The deviance and its exact gradient in θ (the blocked solve only). With A = Λ'Z'ZΛ + I, the penalised
        residual e at (β̂, û), F = A⁻¹Λ'Z'X, R = X − ZΛF and S_X = R'X, for θ_i an entry (r, c) of a factor's T
        (Λ_i = ∂Λ/∂θ_i: a one at (r, c) of every level's block):

            ∂ log|A| = 2 tr(A⁻¹Λ'Z'Z Λ_i),   ∂ r² = −2 (Z'e)'Λ_i û   (û minimises r², so only Λ moves it),
            ∂ log|S_X| = −2 tr(F S_X⁻¹ (Z'R)'Λ_i)   (REML),

        each a sum over the levels of θ_i's factor of per-level blocks."""
        theta = np.asarray(theta, dtype=float)
        effects = self.effects
        try:
            a = effects.curvature(theta, self.tabs)
            b = effects.scale_t(theta, self.zt_yx)
            s = a.solve(b)
            sol = self._profile(float(b[:, 0] @ s[:, 0]), b[:, 1:].T @ s[:, 0], b[:, 1:].T @ s[:, 1:], a.logdet())
        except (np.linalg.LinAlgError, ValueError):  # not positive definite, or not finite
            return 1e300, np.zeros_like(theta)
        r2, dof, beta, rx = sol["r2"], sol["dof"], sol["beta"], sol["rx"]
        if r2 < ROUNDING * self.yty:  # r² is rounding: the model fits every value, and the gradient says nothing
            return sol["deviance"], np.full_like(theta, np.nan)
        f = s[:, 1:]
        u = s[:, 0] - f @ beta
        ze = self.zt_yx[:, 0] - self.zt_yx[:, 1:] @ beta - effects.ztz_times(self.tabs, effects.scale(theta, u))
        h00, h_rest = a.inverse_times_diagonal(*effects.lam_t_ztz(theta, self.tabs))
        if self.reml:
            zr = self.zt_yx[:, 1:] - effects.ztz_times(self.tabs, effects.scale(theta, f))
            fs = f @ cho_solve((rx, True), np.eye(self.p))  # F S_X⁻¹
            fs_levels, zr_levels = effects.level_blocks(fs), effects.level_blocks(zr)
        grad = np.zeros_like(theta)
        for k, (g, ze_g, u_g) in enumerate(zip(effects.groups, effects.level_blocks(ze), effects.level_blocks(u),
                                               strict=True)):
            h = h00 if k == 0 else effects.rest_diagonal(h_rest, k)
            logdet_part = 2 * h[:, g.cols, g.rows].sum(axis=0)
            r2_part = -2 * (ze_g[:, g.rows] * u_g[:, g.cols]).sum(axis=0)
            grad[g.theta] = logdet_part + dof / r2 * r2_part
            if self.reml:
                grad[g.theta] -= 2 * np.einsum("lip,lip->i", fs_levels[k][:, g.cols], zr_levels[k][:, g.rows])
        return sol["deviance"], grad

    def convergence(self, theta: np.ndarray, step: float = 1e-5) -> list[str]:
        """lme4's convergence messages at θ (:mod:`analysis.convergence`): the exact gradient, and its central
        differences for the Hessian — only when the fit is not singular, as lme4 checks."""
        diagonal = self.effects.diagonal
        if is_singular(theta, diagonal):
            return messages(theta, diagonal)
        gradient = self.deviance_and_gradient(theta)[1]
        hessian = gradient_hessian(lambda t: self.deviance_and_gradient(t)[1], theta, step)
        return messages(theta, diagonal, gradient, hessian)

    def start(self, value: float) -> np.ndarray:
        """θ with every term's factor ``value`` times the identity (lme4 starts from 1)."""
        return np.where(self.effects.diagonal, value, 0.0)


def fit_lmm(design: Design, reml: bool = False) -> MixedFit:
    """Gaussian mixed model; ``loglik`` is lme4's ``logLik`` (for REML, ``-REMLcrit / 2``)."""
    if np.ptp(design.y) == 0:
        raise AnalysisError("is constant; there is no variance to model", f"response {design.response!r}")
    model = _Profiled(design, reml)
    best = minimize(model.deviance, [model.start(s) for s in STARTS], model.bounds, model.effects.ways_off_zero,
                    with_gradient=model.deviance_and_gradient)
    if not np.isfinite(best.fun) or best.fun >= 1e300:
        raise AnalysisError("the likelihood could not be evaluated (a fixed effect is confounded with the "
                            "random effects?)", f"response {design.response!r}")
    theta = best.x
    sol = model.solve(theta)
    sigma2 = sol["sigma2"]
    blocks = model.blocks(theta)
    variance = {**components(design.random, blocks, sigma2), "residual": float(sigma2)}
    cov_fixed = sigma2 * cho_solve(cho_factor(sol["xvx"]), np.eye(model.p))
    se = np.sqrt(np.diag(cov_fixed))
    return MixedFit(
        family="gaussian", formula=formula_of(design), nobs=design.nobs,
        groups={t.group: len(t.levels) for t in design.random},
        fixed=dict(zip(design.fixed_names, map(float, sol["beta"]), strict=True)),
        se=dict(zip(design.fixed_names, map(float, se), strict=True)), cov_fixed=cov_fixed, variance=variance,
        loglik=-sol["deviance"] / 2, n_params=model.p + len(theta) + 1, reml=reml,
        optimizer="L-BFGS-B (exact gradient)",
        singular=is_singular(theta, model.effects.diagonal), dropped=design.dropped,
        messages=tuple(model.convergence(theta)), theta=tuple(map(float, theta)))


def components(terms, blocks: list[np.ndarray], scale: float) -> dict[str, float]:
    """lme4's ``VarCorr`` by name: ``group`` for an intercept's variance, ``group:column`` for a slope's,
    ``group:cor(a,b)`` for a correlation (as lme4's ``as.data.frame(VarCorr(m))`` names them); ``scale`` is σ² for
    Gaussian models, 1 for Poisson."""
    out: dict[str, float] = {}
    for t, b in zip(terms, blocks, strict=True):
        cov = scale * b @ b.T
        names = [t.group if n == "(Intercept)" else f"{t.group}:{n}" for n in t.names]
        for i, name in enumerate(names):
            out[name] = float(cov[i, i])
        for j in range(t.width):
            for i in range(j + 1, t.width):
                denom = np.sqrt(cov[i, i] * cov[j, j])
                out[f"{t.group}:cor({t.names[j]},{t.names[i]})"] = float(cov[i, j] / denom) if denom > 0 \
                    else float("nan")
    return out
