"""Linear mixed models by maximum likelihood (or REML) with statsmodels, reported as lme4 reports them.

Crossed random intercepts need statsmodels' one-group formulation: every row in a single group, one variance
component per grouping factor (``groups=participant`` with a scene component would be *nested*, and give a
different likelihood). A single grouping factor with a random slope uses ``groups`` with ``exog_re = [1, x]``.

One optimiser can stop early on a flat likelihood, so each fit is multi-start: BFGS and L-BFGS first; when they
disagree, also CG, Nelder–Mead→BFGS and Powell→BFGS; the best is polished with BFGS. Fixed-effect covariances
are lme4's: σ² (X'V⁻¹X)⁻¹ at the estimated variance components.
"""

from __future__ import annotations

import warnings

import numpy as np
from statsmodels.regression.mixed_linear_model import MixedLM, VCSpec

from .design import Design
from .errors import AnalysisError
from .mixed import MixedFit, formula_of

FIRST = ("bfgs", "lbfgs")
MORE = ("cg", ("nm", "bfgs"), ("powell", "bfgs"))
AGREE = 1e-6  # log-likelihood units


def _model(design: Design, reml: bool) -> MixedLM:
    terms = design.random
    if any(t.slope is not None for t in terms):
        if len(terms) > 1:
            raise AnalysisError("a random slope is supported with a single grouping factor", "--random")
        t = terms[0]
        return MixedLM(design.y, design.X, groups=t.codes, exog_re=np.column_stack([np.ones(design.nobs), t.slope]))
    if len(terms) == 1:
        return MixedLM(design.y, design.X, groups=terms[0].codes)
    vc = VCSpec([t.group for t in terms], [[list(t.levels)] for t in terms], [[t.z().toarray()] for t in terms])
    return MixedLM(design.y, design.X, groups=np.zeros(design.nobs), exog_vc=vc)


def _fit_once(model: MixedLM, reml: bool, method, start=None):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        try:
            return model.fit(reml=reml, method=list(method) if isinstance(method, tuple) else method,
                             start_params=start)
        except (np.linalg.LinAlgError, ValueError, OverflowError):
            return None


def _best_fit(model: MixedLM, reml: bool):
    fits = [(m, r) for m in FIRST if (r := _fit_once(model, reml, m)) is not None and np.isfinite(r.llf)]
    if len(fits) < 2 or abs(fits[0][1].llf - fits[1][1].llf) > AGREE:
        fits += [(m, r) for m in MORE if (r := _fit_once(model, reml, m)) is not None and np.isfinite(r.llf)]
    if not fits:
        raise AnalysisError("every optimiser failed on this model")
    method, best = max(fits, key=lambda mr: mr[1].llf)
    polished = _fit_once(model, reml, "bfgs", start=best.params_object)
    if polished is not None and np.isfinite(polished.llf) and polished.llf > best.llf:
        best = polished
    name = method if isinstance(method, str) else "→".join(method)
    return name, best


def _random_covariances(design: Design, result) -> list[np.ndarray]:
    """Per grouping factor, the covariance matrix of its random effects (1×1 or 2×2), in response units²."""
    terms = design.random
    if len(terms) == 1:
        cov = np.asarray(result.cov_re, dtype=float)
        return [cov.reshape(terms[0].per_level, terms[0].per_level)]
    names = list(result.model.exog_vc.names)
    return [np.array([[float(result.vcomp[names.index(t.group)])]]) for t in terms]


def _fixed_covariance(design: Design, covs: list[np.ndarray], sigma2: float) -> np.ndarray:
    """σ² (X'V⁻¹X)⁻¹ with V = I + Z Λ Λ' Z' (relative covariance), through the q×q system."""
    blocks = []
    for t, cov in zip(design.random, covs, strict=True):
        w, v = np.linalg.eigh(cov / sigma2)
        root = v * np.sqrt(np.clip(w, 0, None))
        blocks += [root] * len(t.levels)
    from scipy.linalg import block_diag

    lam = block_diag(*blocks)
    zl = design.z() @ lam
    X = design.X
    a = np.eye(zl.shape[1]) + zl.T @ zl
    zx = zl.T @ X
    xvx = X.T @ X - zx.T @ np.linalg.solve(a, zx)
    return sigma2 * np.linalg.inv(xvx)


def fit_lmm(design: Design, reml: bool = False) -> MixedFit:
    """Gaussian mixed model; ``loglik`` is lme4's ``logLik`` (for REML, ``-REMLcrit / 2``)."""
    if np.ptp(design.y) == 0:
        raise AnalysisError("is constant; there is no variance to model", f"response {design.response!r}")
    model = _model(design, reml)
    method, r = _best_fit(model, reml)
    sigma2 = float(r.scale)
    covs = _random_covariances(design, r)
    variance: dict[str, float] = {}
    for t, cov in zip(design.random, covs, strict=True):
        variance[t.group] = float(cov[0, 0])
        if t.slope is not None:
            variance[f"{t.group}:{t.slope_name}"] = float(cov[1, 1])
            denom = np.sqrt(cov[0, 0] * cov[1, 1])
            variance[f"{t.group}:cor"] = float(cov[0, 1] / denom) if denom > 0 else float("nan")
    variance["residual"] = sigma2
    cov_fixed = _fixed_covariance(design, covs, sigma2)
    se = np.sqrt(np.diag(cov_fixed))
    n_var = sum(t.per_level * (t.per_level + 1) // 2 for t in design.random) + 1
    singular = any(np.linalg.eigvalsh(c).min() <= 1e-6 * sigma2 for c in covs)
    return MixedFit(
        family="gaussian", formula=formula_of(design), nobs=design.nobs,
        groups={t.group: len(t.levels) for t in design.random},
        fixed=dict(zip(design.fixed_names, map(float, r.fe_params), strict=True)),
        se=dict(zip(design.fixed_names, map(float, se), strict=True)), cov_fixed=cov_fixed, variance=variance,
        loglik=float(r.llf), n_params=design.X.shape[1] + n_var, reml=reml, optimizer=method, singular=singular,
        dropped=design.dropped)
