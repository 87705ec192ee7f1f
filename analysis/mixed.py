"""Mixed models by maximum likelihood, their likelihood-ratio tests and pairwise contrasts.

``fit`` dispatches on the family: Gaussian (linear mixed model, :mod:`analysis.lmm`) or Poisson (log link,
Laplace or adaptive Gauss–Hermite likelihood, :mod:`analysis.glmm`). The numbers reproduce lme4's ``lmer``
(``REML = FALSE``) and ``glmer`` with their default settings; tests compare them with lme4's own output.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass, field

import numpy as np
from scipy import stats

from .design import Design
from .errors import AnalysisError

FAMILIES = ("gaussian", "poisson")


@dataclass(frozen=True)
class MixedFit:
    """A fitted mixed model.

    ``variance`` holds random-effect variances by grouping factor (``"Subject:Days"`` for a slope,
    ``"Subject:cor"`` for the intercept–slope correlation) and ``"residual"`` for Gaussian models.
    ``loglik`` is the maximised log-likelihood (for REML fits, the REML criterion is ``-2 * loglik``).
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

    def to_dict(self) -> dict:
        return {"family": self.family, "formula": self.formula, "nobs": self.nobs, "groups": self.groups,
                "loglik": self.loglik, "reml": self.reml, "n_params": self.n_params,
                "fixed": {k: {"estimate": v, "se": self.se[k]} for k, v in self.fixed.items()},
                "variance": self.variance, "singular": self.singular, "optimizer": self.optimizer,
                "dropped_rows": self.dropped, **self.extra}


@dataclass(frozen=True)
class LRTest:
    """Likelihood-ratio test of nested maximum-likelihood fits: χ²(df) = 2 (ℓ_full − ℓ_null)."""

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


def format_p(p: float) -> str:
    if not np.isfinite(p):
        return "p = n/a"
    if p < 0.001:
        return "p < .001"
    return f"p = {p:.3f}".replace("0.", ".", 1)


def formula_of(design: Design) -> str:
    fixed = " + ".join(design.fixed_terms) or "1"
    random = " + ".join(f"({t.slope_name or 1} | {t.group})" for t in design.random)
    return f"{design.response} ~ {fixed} + {random}"


def fit(design: Design, family: str = "gaussian", *, reml: bool = False, n_agq: int = 1) -> MixedFit:
    """Fit by maximum likelihood (or REML for Gaussian models when ``reml``)."""
    if family == "gaussian":
        from .lmm import fit_lmm

        return fit_lmm(design, reml=reml)
    if family == "poisson":
        from .glmm import fit_poisson

        return fit_poisson(design, n_agq=n_agq)
    raise AnalysisError(f"unknown family {family!r} (choose {' or '.join(FAMILIES)})", "--family")


def lr_test(null: MixedFit, full: MixedFit) -> LRTest:
    if null.reml or full.reml:
        raise AnalysisError("likelihood-ratio tests of fixed effects need maximum-likelihood fits, not REML")
    df = full.n_params - null.n_params
    chi2 = max(0.0, 2.0 * (full.loglik - null.loglik))
    return LRTest(chi2, df, float(stats.chi2.sf(chi2, df)), full.nobs, null.loglik, full.loglik)


@dataclass(frozen=True)
class Comparison:
    """A measure's model with the term, without it, and the LR test between them."""

    full: MixedFit
    null: MixedFit
    lrt: LRTest

    def to_dict(self) -> dict:
        return {**self.full.to_dict(), "lrt": self.lrt.to_dict(), "null": self.null.to_dict()}


def compare(design: Design, term: str, family: str = "gaussian") -> Comparison:
    """Fit with and without the fixed ``term`` and test it."""
    full = fit(design, family)
    null = fit(design.without(term), family)
    return Comparison(full, null, lr_test(null, full))


@dataclass(frozen=True)
class Contrast:
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


def holm(p: list[float]) -> list[float]:
    """Holm's step-down adjusted p-values, in the input order."""
    order = np.argsort(p)
    m = len(p)
    adjusted = np.empty(m)
    running = 0.0
    for k, i in enumerate(order):
        running = max(running, min(1.0, (m - k) * p[i]))
        adjusted[i] = running
    return adjusted.tolist()


def pairwise(fitted: MixedFit, term: str, levels: list[str]) -> list[Contrast]:
    """Wald z contrasts between every pair of ``levels`` of a treatment-coded term (later − earlier),
    Holm-corrected. Estimates are on the model's scale (log rate for Poisson)."""
    names = list(fitted.fixed)
    index = {lv: (names.index(f"{term}{lv}") if f"{term}{lv}" in names else None) for lv in levels}
    if sum(i is None for i in index.values()) != 1:
        raise AnalysisError(f"the model has no treatment coding of {term!r} over {levels}")
    beta = np.array(list(fitted.fixed.values()))
    rows = []
    for a, b in itertools.combinations(levels, 2):
        c = np.zeros(len(beta))
        if index[b] is not None:
            c[index[b]] += 1
        if index[a] is not None:
            c[index[a]] -= 1
        est = float(c @ beta)
        se = float(np.sqrt(c @ fitted.cov_fixed @ c))
        z = est / se if se > 0 else float("nan")
        rows.append((b, a, est, se, z, float(2 * stats.norm.sf(abs(z)))))
    adjusted = holm([r[5] for r in rows])
    return [Contrast(*r, p_holm=h) for r, h in zip(rows, adjusted, strict=True)]
