"""Choosing each measure's random effects as an analyst would, by a stated, published rule, and testing condition
under the structure kept.

1. Start maximal: correlated random slopes of condition by participant and by scene, as the design supports them
   (Barr, Levy, Scheepers & Tily 2013, "keep it maximal"). A slope the design cannot support — condition never
   varies within a level of the factor, or more random effects than observations — is left out before fitting,
   and the step says why.
2. While the fit is singular (a variance at zero or a correlation at ±1, lme4's ``isSingular``) or lme4's
   convergence check says it failed to converge (:func:`analysis.convergence.failed`; a badly scaled Hessian alone
   is reported, not acted on): first leave out the correlations (the zero-correlation-parameter model of Bates, Kliegl,
   Vasishth & Baayen 2015, "Parsimonious mixed models"), then the random slope with the smallest variance, one
   at a time (Matuschek, Kliegl, Vasishth, Baayen & Bates 2017: simplify until the model is supported by the
   data). Random intercepts are never left out: the intercept-only model is where the rule stops, singular or not
   (the report marks it so).
3. Test condition by likelihood ratio under the structure kept (the null model keeps the same random effects).

Beside it, the same test with random intercepts only, and whether that model would have reached another
conclusion at α = .05.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import pandas as pd

from .convergence import failed
from .design import build_design
from .errors import AnalysisError
from .mixed import compare, fit
from .results import Comparison, format_p

ALPHA = 0.05
GROUPS = ("participant", "scene")


@dataclass(frozen=True)
class Structure:
    """Random effects by grouping factor: the slopes (fixed-effect column names, the condition's dummies) each
    factor has besides its intercept, and whether they are correlated with it and each other."""

    slopes: tuple[tuple[str, tuple[str, ...]], ...]
    correlated: bool

    def specs(self, term: str) -> list[str]:
        """``--random`` specs for :func:`analysis.design.build_design` (dummy columns by the fixed effects' names)."""
        out = []
        for group, slopes in self.slopes:
            if not slopes:
                out.append(group)
            elif self.correlated:
                out.append(f"{term}|{group}")
            else:
                out += [group] + [f"0 + {s}|{group}" for s in slopes]
        return out

    def name(self, term: str = "condition") -> str:
        """A short name: which slopes (``term``'s levels) by which factor, correlated or not."""
        with_slopes = [(g, s) for g, s in self.slopes if s]
        if not with_slopes:
            return "intercepts only"
        kind = "correlated" if self.correlated else "uncorrelated"
        parts = [f"{', '.join(s.removeprefix(term) for s in slopes)} by {group}" for group, slopes in with_slopes]
        return f"{kind} slopes of " + "; ".join(parts)

    def without(self, group: str, slope: str) -> Structure:
        return Structure(tuple((g, tuple(x for x in s if not (g == group and x == slope))) for g, s in self.slopes),
                         self.correlated)


@dataclass
class Step:
    """One structure tried: its formula, whether its fit was singular, lme4's messages, its variance components,
    and what was done next and why."""

    formula: str
    structure: str
    singular: bool = False
    messages: tuple[str, ...] = ()
    decision: str = ""
    variances: dict[str, float] = field(default_factory=dict)

    def to_dict(self) -> dict:
        return {"formula": self.formula, "structure": self.structure, "singular": self.singular,
                "messages": list(self.messages), "decision": self.decision, "variances": self.variances}


@dataclass
class Selection:
    """The steps, the structure kept and its test of condition, and the intercept-only test beside it."""

    steps: list[Step] = field(default_factory=list)
    kept: Structure | None = None
    comparison: Comparison | None = None
    intercepts: Comparison | None = None

    def sentence(self, term: str = "condition") -> str:
        """Whether random intercepts alone would have changed the conclusion, with both p-values."""
        if self.comparison is None or self.intercepts is None or self.kept is None:
            return ""
        p, p0 = self.comparison.lrt.p, self.intercepts.lrt.p
        if not any(s for _, s in self.kept.slopes):
            return f"The model kept has random intercepts only ({format_p(p)})."
        same = (p < ALPHA) == (p0 < ALPHA)
        verdict = "the same conclusion" if same else "a different conclusion"
        return (f"With random intercepts only, the test of {term} gives {format_p(p0)} against {format_p(p)} under "
                f"the {self.kept.name()}: {verdict} at α = {ALPHA:g}.")


def with_dummies(frame: pd.DataFrame, term: str, levels: list[str]) -> pd.DataFrame:
    """``frame`` with the treatment dummies of ``term`` as numeric columns named as the fixed effects are
    (``conditionbasic``): what an uncorrelated slope of one level is fitted on."""
    extra = {f"{term}{lv}": (frame[term] == lv).astype(float) for lv in levels[1:]}
    clash = sorted(set(extra) & set(frame.columns))
    if clash:
        raise AnalysisError(f"the data already have a column {clash[0]!r}, the name of a dummy of {term}", "column")
    return frame.assign(**extra)


def choose(frame: pd.DataFrame, measure: str, family: str, term: str = "condition",
           groups: tuple[str, ...] = GROUPS) -> Selection:
    """The rule of this module for ``measure`` of ``frame`` (``term`` a pandas Categorical; ``groups`` with a
    single level are left out, as they are from every model). A measure the data cannot inform raises
    :class:`analysis.degenerate.NotModelled` from the intercept-only test, as before."""
    frame = frame.dropna(subset=[measure])
    groups = tuple(g for g in groups if frame[g].nunique() > 1)
    levels = [str(c) for c in frame[term].cat.categories if (frame[term] == c).any()]
    data = with_dummies(frame, term, levels)
    dummies = tuple(f"{term}{lv}" for lv in levels[1:])
    selection = Selection()
    # the intercept-only test first: it is the floor of the rule, and it names a measure nothing can inform
    selection.intercepts = compare(build_design(data, measure, [term], list(groups)), term, family)
    structure = Structure(tuple((g, dummies) for g in groups), correlated=True)
    for group in groups:  # what the design cannot support is left out before fitting
        try:
            build_design(data, measure, [term], [f"{term}|{group}"])
        except AnalysisError as e:
            selection.steps.append(Step(formula="", structure=f"slopes of {term} by {group}",
                                        decision=f"left out before fitting: {e.message}"))
            structure = Structure(tuple((g, () if g == group else s) for g, s in structure.slopes), True)
    while any(s for _, s in structure.slopes):
        design = build_design(data, measure, [term], structure.specs(term))
        fitted = fit(design, family)
        step = Step(fitted.formula, structure.name(term), fitted.singular, fitted.messages,
                    variances={k: v for k, v in fitted.variance.items() if ":cor(" not in k})
        selection.steps.append(step)
        if not (fitted.singular or failed(fitted.messages)):
            step.decision = "kept: not singular, converged"
            selection.kept = structure
            selection.comparison = compare(design, term, family, full=fitted)
            return selection
        why = "singular" if fitted.singular else "did not converge"
        if structure.correlated:
            step.decision = f"{why}: leave out the correlations"
            structure = Structure(structure.slopes, correlated=False)
            continue
        group, slope, variance = min(((g, s, fitted.variance[f"{g}:{s}"]) for g, slopes in structure.slopes
                                      for s in slopes), key=lambda x: x[2])
        step.decision = f"{why}: leave out the slope of {slope.removeprefix(term)} by {group} (the smallest " \
                        f"variance, {variance:.3g})"
        structure = structure.without(group, slope)
    selection.steps.append(Step(selection.intercepts.full.formula, "intercepts only",
                                selection.intercepts.full.singular, selection.intercepts.full.messages,
                                "kept: random intercepts are never left out"))
    selection.kept, selection.comparison = structure, selection.intercepts
    return selection
