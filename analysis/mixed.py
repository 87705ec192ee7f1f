"""Mixed models by maximum likelihood, their likelihood-ratio tests and pairwise contrasts.

``fit`` dispatches on the family: Gaussian (linear mixed model, :mod:`analysis.lmm`) or Poisson (log link,
Laplace or adaptive Gauss–Hermite likelihood, :mod:`analysis.glmm`). The numbers reproduce lme4's ``lmer``
(``REML = FALSE``) and ``glmer`` run to convergence (their defaults stop a little early: see
:mod:`analysis.glmm`); tests compare them with lme4's own output, on random studies in every run. What
they return (:class:`MixedFit`, :class:`LRTest`, :class:`Comparison`, :class:`Contrast`) is in
:mod:`analysis.results`.
"""

from __future__ import annotations

import itertools

import numpy as np
from scipy import stats

from .degenerate import check_data, check_fit
from .design import Design
from .errors import AnalysisError
from .glmm import fit_poisson
from .lmm import fit_lmm
from .results import Comparison, Contrast, LRTest, MixedFit

FAMILIES = ("gaussian", "poisson")


def fit(design: Design, family: str = "gaussian", *, reml: bool = False, n_agq: int = 1) -> MixedFit:
    """Fit by maximum likelihood (or REML for Gaussian models when ``reml``)."""
    if family == "gaussian":
        return fit_lmm(design, reml=reml)
    if family == "poisson":
        return fit_poisson(design, n_agq=n_agq)
    raise AnalysisError(f"unknown family {family!r} (choose {' or '.join(FAMILIES)})", "--family")


def lr_test(null: MixedFit, full: MixedFit) -> LRTest:
    """``anova(null, full)``: df is the difference in estimated parameters; a χ² below 0 (the null fitted
    slightly better) counts as 0, as in lme4's ``anova``."""
    if null.reml or full.reml:
        raise AnalysisError("likelihood-ratio tests of fixed effects need maximum-likelihood fits, not REML")
    df = full.n_params - null.n_params
    chi2 = max(0.0, 2.0 * (full.loglik - null.loglik))
    return LRTest(chi2, df, float(stats.chi2.sf(chi2, df)), full.nobs, null.loglik, full.loglik)


def compare(design: Design, term: str, family: str = "gaussian", full: MixedFit | None = None) -> Comparison:
    """Fit with and without the fixed ``term`` (``full``: the fit with it, when it is already made) and test it; a
    test the data cannot inform, or a degenerate fit, raises :class:`analysis.degenerate.NotModelled` naming why
    (never a test or contrast from it)."""
    if term in dict(design.levels):
        check_data(design, term, family)
    full = full or fit(design, family)
    null = fit(design.without(term), family)
    comparison = Comparison(full, null, lr_test(null, full))
    check_fit(design, comparison)
    return comparison


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
