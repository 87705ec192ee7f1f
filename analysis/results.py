"""What the mixed models return: frozen values built by :mod:`analysis.lmm`, :mod:`analysis.glmm` and
:mod:`analysis.mixed`, read by the tables, the report and ``analyze lmm``. They depend on nothing else in the
package, so the fitting modules and the dispatcher in :mod:`analysis.mixed` can all import them.

Scales follow lme4: fixed effects, their SEs and contrasts are on the linear predictor's scale (response units
for Gaussian models, log rate for Poisson); variances are in that scale's units squared; log-likelihoods are
natural logarithms (lme4's ``logLik``).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


@dataclass(frozen=True)
class MixedFit:
    """A fitted mixed model.

    ``variance`` holds random-effect variances by grouping factor (``"Subject:Days"`` for a slope,
    ``"Subject:cor((Intercept),Days)"`` for a correlation) and ``"residual"`` for Gaussian models: lme4's
    ``VarCorr`` as ``vcov`` in the linear predictor's units squared (log rate² for Poisson; per slope unit
    squared for a slope), the correlation as ``sdcor``.
    ``loglik`` is the maximised log-likelihood (for REML fits, the REML criterion is ``-2 * loglik``).

    ``fixed`` and ``se`` are lme4's ``fixef`` and their standard errors, ``cov_fixed`` its ``vcov`` (in
    ``fixed``'s order); ``groups`` is ``ngrps`` (levels per grouping factor); ``n_params`` counts what lme4's
    ``df`` of ``logLik`` counts (fixed effects, covariance parameters and σ for Gaussian models); the LR test's
    degrees of freedom come from it. ``dropped`` rows had a missing value; ``extra`` is family-specific
    (``n_agq`` for Poisson) and goes into :meth:`to_dict` as it is. ``singular`` and ``messages`` are lme4's
    ``isSingular`` and its convergence messages, in its words (:mod:`analysis.convergence`); ``theta`` the
    relative covariance factors' entries at the optimum, term by term as the formula lists them (lme4 lists terms
    by decreasing number of levels when that order differs: compare by name, not position).
    """

    family: str
    formula: str
    nobs: int
    groups: dict[str, int]
    fixed: dict[str, float]
    se: dict[str, float]
    cov_fixed: np.ndarray
    variance: dict[str, float]
    loglik: float
    n_params: int
    reml: bool = False
    optimizer: str = ""
    singular: bool = False
    dropped: int = 0
    extra: dict = field(default_factory=dict)
    messages: tuple[str, ...] = ()
    theta: tuple[float, ...] = ()

    def to_dict(self) -> dict:
        return {"family": self.family, "formula": self.formula, "nobs": self.nobs, "groups": self.groups,
                "loglik": self.loglik, "reml": self.reml, "n_params": self.n_params,
                "fixed": {k: {"estimate": v, "se": self.se[k]} for k, v in self.fixed.items()},
                "variance": self.variance, "singular": self.singular, "messages": list(self.messages),
                "optimizer": self.optimizer,
                "dropped_rows": self.dropped, **self.extra}


@dataclass(frozen=True)
class LRTest:
    """Likelihood-ratio test of nested maximum-likelihood fits: χ²(df) = 2 (ℓ_full − ℓ_null).

    ``df`` is the difference in estimated parameters, ``p`` the upper tail of χ²(df) (R's
    ``pchisq(chi2, df, lower.tail = FALSE)``), ``nobs`` the N reported with it; the log-likelihoods are lme4's
    ``logLik`` of the two fits, as ``anova()`` lists them.
    """

    chi2: float
    df: int
    p: float
    nobs: int
    null_loglik: float
    full_loglik: float

    def to_dict(self) -> dict:
        return {"chi2": self.chi2, "df": self.df, "p": self.p, "n": self.nobs, "null_loglik": self.null_loglik,
                "full_loglik": self.full_loglik}

    def text(self) -> str:
        """APA style: χ²(2, N = 180) = 12.34, p < .001."""
        return f"χ²({self.df}, N = {self.nobs}) = {self.chi2:.2f}, {format_p(self.p)}"


@dataclass(frozen=True)
class Comparison:
    """A measure's model with the term, without it, and the LR test between them."""

    full: MixedFit
    null: MixedFit
    lrt: LRTest

    def to_dict(self) -> dict:
        return {**self.full.to_dict(), "lrt": self.lrt.to_dict(), "null": self.null.to_dict()}


@dataclass(frozen=True)
class Contrast:
    """Wald z test of level ``a`` minus level ``b`` in the full model: ``estimate`` and ``se`` on the model's
    scale (a log rate ratio for Poisson), ``p`` two-sided, ``p_holm`` Holm-adjusted over the measure's
    contrasts."""

    a: str
    b: str
    estimate: float
    se: float
    z: float
    p: float
    p_holm: float

    def to_dict(self) -> dict:
        return {"contrast": f"{self.a} − {self.b}", "estimate": self.estimate, "se": self.se, "z": self.z,
                "p": self.p, "p_holm": self.p_holm}


def format_p(p: float) -> str:
    """APA style: no leading zero, three decimals, ``p < .001`` below that."""
    if not np.isfinite(p):
        return "p = n/a"
    if p < 0.001:
        return "p < .001"
    return f"p = {p:.3f}".replace("0.", ".", 1)
