"""When a test of condition would say nothing true: the one rule that names a measure as not modelled.

A mixed model of a measure tests condition only when the data can inform it. Before fitting
(:func:`check_data`):

- a Gaussian measure with no variance at all, or with none *within* a condition that has two or more values (a
  ceiling or a floor: every trial of ``basic`` scored 1) — the model's one residual variance would then be
  estimated from the other conditions alone and its contrasts claim a certainty the data do not have;
- a Poisson count that is zero in every row, or in every row of a condition (its log rate has no finite estimate).

After fitting (:func:`check_fit`), a fit that is degenerate whatever the data looked like:

- the residual variance is below a millionth of the response's variance: the model reproduces every value, and
  its standard errors are rounding noise (lme4's optimiser stops near 1e-10 of it by roundoff, this package's fit
  at zero; no behavioural measure explains 99.9999% of its variance);
- the full model's log-likelihood is below the null model's by more than 1e-6 (the null is nested in it, so the
  optimiser failed);
- an estimate or standard error that is not a finite number, or a standard error of zero.

``report/reproduce.R`` applies the same rule with the same words (:mod:`analysis.reproduce`), so the report and
lme4 name the same measures as not modelled, for the same reason.
"""

from __future__ import annotations

import numpy as np

from .design import Design
from .errors import AnalysisError
from .results import Comparison

#: The residual variance, as a share of the response's (sample) variance, below which a fit is exact.
EXACT_FIT = 1e-6
#: How far (log-likelihood units) the full model may fall below its nested null before the fit counts as failed.
LOGLIK_SLACK = 1e-6


class NotModelled(AnalysisError):
    """A measure the data cannot inform a test of: ``message`` is the reason, as the report and reproduce.R print
    it; ``where`` names the response."""


def check_data(design: Design, term: str, family: str) -> None:
    """Raise :class:`NotModelled` when ``design``'s response cannot inform a test of the fixed ``term`` (a
    categorical term of the design)."""
    _raise_for(design, data_problem(design, term, family))


def check_fit(design: Design, comparison: Comparison) -> None:
    """Raise :class:`NotModelled` when the fitted pair is degenerate (see the module's docstring)."""
    _raise_for(design, fit_problem(design, comparison))


def data_problem(design: Design, term: str, family: str) -> str | None:
    """Why the data cannot inform a test of ``term`` (None: they can)."""
    y = design.y
    if family == "poisson":
        if not np.any(y):
            return "is zero everywhere; there is nothing to model"
        zero = [level for level, rows in design.level_rows(term) if not np.any(y[rows])]
        if zero:
            return f"is zero in every row of {_joined(zero)}: its log rate there has no finite estimate (a floor)"
        return None
    if np.ptp(y) == 0:
        return "is constant; there is no variance to model"
    flat = [(level, y[rows][0]) for level, rows in design.level_rows(term) if len(rows) > 1 and np.ptp(y[rows]) == 0]
    if flat:
        values = "; ".join(f"every value in {level} is {value:g}" for level, value in flat)
        return (f"has no variance within a level of {term} ({values}): a ceiling or a floor, which a linear model "
                "with one residual variance cannot describe")
    return None


def fit_problem(design: Design, comparison: Comparison) -> str | None:
    """Why the fitted pair is degenerate (None: it is not)."""
    full, null = comparison.full, comparison.null
    if full.family == "gaussian" and len(design.y) > 1 \
            and full.variance["residual"] < EXACT_FIT * float(np.var(design.y, ddof=1)):
        return "the model reproduces every value exactly (no residual variance): its standard errors are rounding noise"
    if full.loglik < null.loglik - LOGLIK_SLACK:
        return (f"the fit failed: the model with condition has a lower log-likelihood ({full.loglik:.6g}) than the "
                f"model without it ({null.loglik:.6g})")
    values = list(full.fixed.values()) + list(full.se.values())
    if not np.all(np.isfinite(values)) or min(full.se.values()) <= 0:
        return "the fit is degenerate: an estimate or standard error is not a finite positive number"
    return None


def _raise_for(design: Design, reason: str | None) -> None:
    if reason is not None:
        raise NotModelled(reason, f"response {design.response!r}")


def _joined(levels: list[str]) -> str:
    return ", ".join(levels[:-1]) + " and " + levels[-1] if len(levels) > 1 else levels[0]
