"""Linear mixed models by maximum likelihood (or REML), computed as lme4 computes them.

lme4's profiled deviance (Bates, Mächler, Bolker & Walker 2015, §3): random effects b = Λ_θ u with spherical u;
for given θ the fixed effects and σ² have closed forms, so the optimiser only searches θ (one relative standard
deviation per random intercept; the three entries of a lower-triangular 2×2 factor per intercept–slope term).
Everything is computed from the cross-products Z'Z, Z'X, Z'y, X'X, X'y, y'y, so an evaluation costs one
Cholesky factorisation of a q×q matrix (q = random-effect levels) whatever the number of rows — and with random
intercepts only (every model of the report), one of the small Schur complement of :mod:`analysis.crossed`.

statsmodels' MixedLM gives the same estimates (crossed factors as variance components of one group) but takes
~20 s per fit on 1800 rows with 200 participants, because it works on the dense n×q design of that one group;
this formulation takes well under a second, which is what keeps the report's budget.

The flat likelihood in a variance near zero can stop one optimiser early, so each fit is multi-start (bounded
L-BFGS-B from θ = 1, 0.1 and 3, the best restarted and moved off zero variances by :mod:`analysis.optimum`, then
polished by Nelder–Mead). Fixed-effect covariances are lme4's σ² (X'V⁻¹X)⁻¹.
"""

from __future__ import annotations

import numpy as np
from scipy import optimize
from scipy.linalg import block_diag, cho_factor, cho_solve, solve_triangular

from .crossed import CrossedIntercepts
from .design import Design, formula_of
from .errors import AnalysisError
from .optimum import minimize
from .results import MixedFit

STARTS = (1.0, 0.1, 3.0)


class _Profiled:
    """−2 log-likelihood (or the REML criterion) as a function of θ alone."""

    def __init__(self, design: Design, reml: bool, crossed: bool = True):
        """``crossed``: solve random intercepts through :mod:`analysis.crossed` (False: the dense q×q solve that
        slopes need, kept for them and for tests that compare the two)."""
        self.design, self.reml = design, reml
        X, y = design.X, design.y
        self.n, self.p = X.shape
        self.xtx, self.xty, self.yty = X.T @ X, X.T @ y, float(y @ y)
        if crossed and all(t.slope is None for t in design.random):
            # Crossed intercepts: cross-tabulations and per-level sums, factors largest first (analysis.crossed).
            self.order = sorted(range(len(design.random)), key=lambda i: -len(design.random[i].levels))
            self.crossed = CrossedIntercepts([design.random[i] for i in self.order])
            self.tabs = self.crossed.crosstabs(np.ones(self.n))
            self.zt_yx = self.crossed.zt(np.column_stack([y, X]))
            self.q = self.crossed.q
        else:
            self.crossed = None
            Z = design.z()
            self.ztz = (Z.T @ Z).toarray()
            self.ztx = np.asarray(Z.T @ X)
            self.zty = np.asarray(Z.T @ y)
            self.q = self.ztz.shape[0]
        #: per term: (number of θ, size of the block)
        self.shapes = [(1, 1) if t.slope is None else (3, 2) for t in design.random]
        self.bounds = [bound for n, _ in self.shapes for bound in
                       ([(0, None)] if n == 1 else [(0, None), (None, None), (0, None)])]

    def blocks(self, theta: np.ndarray) -> list[np.ndarray]:
        """The relative covariance factor of each term (1×1 or lower-triangular 2×2)."""
        out, i = [], 0
        for n, _ in self.shapes:
            if n == 1:
                out.append(np.array([[theta[i]]]))
            else:
                out.append(np.array([[theta[i], 0.0], [theta[i + 1], theta[i + 2]]]))
            i += n
        return out

    def lam(self, theta: np.ndarray) -> np.ndarray:
        parts = [np.kron(np.eye(len(t.levels)), b) for t, b in zip(self.design.random, self.blocks(theta),
                                                                    strict=True)]
        return block_diag(*parts)

    def _products(self, theta: np.ndarray) -> tuple[float, np.ndarray, np.ndarray, float]:
        """With A = Λ'Z'ZΛ + I = LL': ‖L⁻¹Λ'Z'y‖², (L⁻¹Λ'Z'X)'(L⁻¹Λ'Z'y), (L⁻¹Λ'Z'X)'(L⁻¹Λ'Z'X) and log det A."""
        if self.crossed is not None:
            th = np.asarray(theta, dtype=float)[self.order]
            a = self.crossed.curvature(th, self.tabs)
            b = self.zt_yx * self.crossed.scale(th)[:, None]  # Λ'Z'[y X]
            s = a.solve(b)
            return float(b[:, 0] @ s[:, 0]), b[:, 1:].T @ s[:, 0], b[:, 1:].T @ s[:, 1:], a.logdet()
        lam = self.lam(theta)
        chol = np.linalg.cholesky(lam.T @ self.ztz @ lam + np.eye(self.q))
        cu = solve_triangular(chol, lam.T @ self.zty, lower=True)
        rzx = solve_triangular(chol, lam.T @ self.ztx, lower=True)
        return float(cu @ cu), rzx.T @ cu, rzx.T @ rzx, 2 * float(np.log(np.diag(chol)).sum())

    def solve(self, theta: np.ndarray) -> dict:
        cu_cu, rzx_cu, rzx_rzx, logdet_l = self._products(theta)
        xvx = self.xtx - rzx_rzx
        rx = np.linalg.cholesky(xvx)
        cb = solve_triangular(rx, self.xty - rzx_cu, lower=True)
        r2 = max(self.yty - cu_cu - cb @ cb, 1e-300)
        if self.reml:
            dof = self.n - self.p
            dev = logdet_l + 2 * np.log(np.diag(rx)).sum() + dof * (1 + np.log(2 * np.pi * r2 / dof))
        else:
            dof = self.n
            dev = logdet_l + dof * (1 + np.log(2 * np.pi * r2 / dof))
        beta = solve_triangular(rx.T, cb, lower=False)
        return {"deviance": float(dev), "beta": beta, "sigma2": r2 / dof, "xvx": xvx}

    def deviance(self, theta: np.ndarray) -> float:
        try:
            return self.solve(theta)["deviance"]
        except np.linalg.LinAlgError:
            return 1e300

    def start(self, value: float) -> np.ndarray:
        return np.concatenate([[value] if n == 1 else [value, 0.0, value] for n, _ in self.shapes])


def fit_lmm(design: Design, reml: bool = False) -> MixedFit:
    """Gaussian mixed model; ``loglik`` is lme4's ``logLik`` (for REML, ``-REMLcrit / 2``)."""
    if np.ptp(design.y) == 0:
        raise AnalysisError("is constant; there is no variance to model", f"response {design.response!r}")
    model = _Profiled(design, reml)
    best = minimize(model.deviance, [model.start(s) for s in STARTS], model.bounds,
                    [i for i, (low, _) in enumerate(model.bounds) if low == 0])
    # Polish: Nelder–Mead needs no gradient, so it can settle θ to ~1e-9 where finite differences cannot.
    again = optimize.minimize(model.deviance, best.x, method="Nelder-Mead", bounds=model.bounds,
                              options={"xatol": 1e-9, "fatol": 1e-10, "maxiter": 2000})
    best = again if again.fun <= best.fun else best
    if not np.isfinite(best.fun) or best.fun >= 1e300:
        raise AnalysisError("the likelihood could not be evaluated (a fixed effect is confounded with the "
                            "random effects?)", f"response {design.response!r}")
    theta = best.x
    sol = model.solve(theta)
    sigma2 = sol["sigma2"]
    variance: dict[str, float] = {}
    blocks = model.blocks(theta)
    for t, b in zip(design.random, blocks, strict=True):
        cov = sigma2 * b @ b.T
        variance[t.group] = float(cov[0, 0])
        if t.slope is not None:
            variance[f"{t.group}:{t.slope_name}"] = float(cov[1, 1])
            denom = np.sqrt(cov[0, 0] * cov[1, 1])
            variance[f"{t.group}:cor"] = float(cov[0, 1] / denom) if denom > 0 else float("nan")
    variance["residual"] = float(sigma2)
    cov_fixed = sigma2 * cho_solve(cho_factor(sol["xvx"]), np.eye(model.p))
    se = np.sqrt(np.diag(cov_fixed))
    return MixedFit(
        family="gaussian", formula=formula_of(design), nobs=design.nobs,
        groups={t.group: len(t.levels) for t in design.random},
        fixed=dict(zip(design.fixed_names, map(float, sol["beta"]), strict=True)),
        se=dict(zip(design.fixed_names, map(float, se), strict=True)), cov_fixed=cov_fixed, variance=variance,
        loglik=-sol["deviance"] / 2, n_params=model.p + len(theta) + 1, reml=reml, optimizer="L-BFGS-B",
        singular=any(abs(np.diag(b)).min() < 1e-4 for b in blocks), dropped=design.dropped)
