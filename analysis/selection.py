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
   at a time. Matuschek, Kliegl, Vasishth, Baayen & Bates (2017) argue for simplifying until the model is
   supported by the data (they judge support by likelihood-ratio tests or AIC); the criterion here is lme4's own,
   singularity and convergence, as in Bates et al.'s iterative reduction. Random intercepts are never left out:
   an uncorrelated fit that is singular only because a random intercept's variance is at zero (a factor that
   explains nothing, as scenes of one difficulty) is kept, and the intercept-only model is where the rule stops,
   singular or not (the report marks both so). A group by which any level of condition never varies gets no
   slopes at all (the pre-check fits the whole factor's slopes). Slopes are on the treatment dummies of the fixed
   effect, so which slope is smallest depends on the reference level (sum coding would not).
3. Test condition by likelihood ratio under the structure kept (the null model keeps the same random effects).

Beside it, the same test with random intercepts only, and whether that model would have reached another
conclusion at α = .05.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from .convergence import SINGULAR_TOL, failed
from .design import build_design, formula_of
from .errors import AnalysisError
from .mixed import compare, fit
from .results import Comparison, format_p

ALPHA = 0.05
#: What a fit of a structure with slopes may raise: the structure is then simplified, never the measure lost.
FAILURES = (AnalysisError, np.linalg.LinAlgError, ValueError, FloatingPointError)
GROUPS = ("participant", "scene")
#: Why the report leaves a count's slopes out: the rule fits them (``choose(..., count_slopes=True)``), but on the
#: benchmark's 2,000 × 9 study its Poisson fits with slopes took the report from 70 s to 274 s (budget 90 s)
COUNT_SLOPES = ("the report does not fit a count's random slopes yet: its Poisson models with slopes take too long "
                "for a large study (analyze lmm --family poisson fits them)")


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

    def lme4(self, column=lambda slope: slope) -> str:
        """The random part of lme4's formula, a slope's column named by ``column`` (reproduce.R's dummies):
        ``(1 + conditionbasic | participant) + (1 | scene)``, or ``(1 | g) + (0 + conditionbasic | g)`` uncorrelated."""
        out = []
        for group, slopes in self.slopes:
            if self.correlated and slopes:
                out.append(f"(1 + {' + '.join(map(column, slopes))} | {group})")
            else:
                out += [f"(1 | {group})"] + [f"(0 + {column(s)} | {group})" for s in slopes]
        return " + ".join(out)

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
    failed: bool = False  # the structure could not be made or fitted (``messages`` says why)

    @property
    def status(self) -> str:
        """What became of the structure: left out (before fitting), failed, singular or not singular."""
        if self.failed:
            return "failed"
        if not self.formula:
            return "left out"
        return "singular" if self.singular else "not singular"

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

    def to_dict(self) -> dict:
        """The steps, the structure kept (name and lme4's random part), the intercept-only test and the sentence."""
        return {"steps": [s.to_dict() for s in self.steps],
                "kept": self.kept.name() if self.kept else None,
                "random": self.kept.lme4() if self.kept else None,
                "intercepts_only": self.intercepts.lrt.to_dict() if self.intercepts else None,
                "sentence": self.sentence()}

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
                f"the {self.kept.name()}: {verdict} at α = {str(ALPHA).lstrip('0')}.")


def _reason(e: Exception) -> str:
    return e.message if isinstance(e, AnalysisError) else str(e)


def _zero(fitted) -> list[str]:
    """The variance components of a fit at zero in lme4's sense: θ (a Gaussian model's standard deviation relative
    to the residual's, a Poisson model's itself) below ``check.conv.singular``'s tolerance."""
    residual = fitted.variance.get("residual", 1.0)  # a GLMM's θ is the standard deviation itself
    return [k for k, v in fitted.variance.items()
            if k != "residual" and ":cor(" not in k and v < SINGULAR_TOL ** 2 * residual]


def _zero_slopes(fitted) -> list[str]:
    return [k for k in _zero(fitted) if ":" in k]


def with_dummies(frame: pd.DataFrame, term: str, levels: list[str]) -> pd.DataFrame:
    """``frame`` with the treatment dummies of ``term`` as numeric columns named as the fixed effects are
    (``conditionbasic``): what an uncorrelated slope of one level is fitted on."""
    extra = {f"{term}{lv}": (frame[term] == lv).astype(float) for lv in levels[1:]}
    clash = sorted(set(extra) & set(frame.columns))
    if clash:
        raise AnalysisError(f"the data already have a column {clash[0]!r}, the name of a dummy of {term}", "column")
    return frame.assign(**extra)


def choose(frame: pd.DataFrame, measure: str, family: str, term: str = "condition",
           groups: tuple[str, ...] = GROUPS, count_slopes: bool = False) -> Selection:
    """The rule of this module for ``measure`` of ``frame`` (``term`` a pandas Categorical; ``groups`` with a
    single level are left out, as they are from every model). A measure the data cannot inform raises
    :class:`analysis.degenerate.NotModelled` from the intercept-only test, as before. A count (Poisson) starts at
    random intercepts unless ``count_slopes`` (:data:`COUNT_SLOPES`)."""
    frame = frame.dropna(subset=[measure])
    groups = tuple(g for g in groups if frame[g].nunique() > 1)
    levels = [str(c) for c in frame[term].cat.categories if (frame[term] == c).any()]
    data = with_dummies(frame, term, levels)
    dummies = tuple(f"{term}{lv}" for lv in levels[1:])
    selection = Selection()
    # the intercept-only test first: it is the floor of the rule, and it names a measure nothing can inform
    selection.intercepts = compare(build_design(data, measure, [term], list(groups)), term, family)
    structure = Structure(tuple((g, dummies) for g in groups), correlated=True)
    for group in groups:  # what the design or the model cannot support is left out before fitting
        try:
            if family != "gaussian" and not count_slopes:
                raise AnalysisError(COUNT_SLOPES)
            build_design(data, measure, [term], [f"{term}|{group}"])
        except AnalysisError as e:
            selection.steps.append(Step(formula="", structure=f"slopes of {term} by {group}",
                                        decision=f"left out before fitting: {e.message}"))
            structure = Structure(tuple((g, () if g == group else s) for g, s in structure.slopes), True)
    while any(s for _, s in structure.slopes):
        design = fitted = None
        try:
            design = build_design(data, measure, [term], structure.specs(term))
            fitted = fit(design, family)
        except FAILURES as e:
            # a model that cannot be made or fitted (a level's name the formula cannot hold, a numerical failure)
            # is simplified as one that does not converge; the intercept-only model it ends in is fitted already
            step = Step(formula_of(design) if design else "", structure.name(term),
                        messages=(f"the fit failed: {_reason(e)}",), failed=True)
        else:
            step = Step(fitted.formula, structure.name(term), fitted.singular, fitted.messages,
                        variances={k: v for k, v in fitted.variance.items() if ":cor(" not in k})
        selection.steps.append(step)
        converged = fitted is not None and not failed(fitted.messages)
        # an uncorrelated fit singular only in a random intercept stands: the rule never leaves one out
        supported = converged and (not fitted.singular or not structure.correlated and not _zero_slopes(fitted))
        why = "the fit failed" if fitted is None else "singular" if fitted.singular else "did not converge"
        if supported:
            try:
                selection.comparison = compare(design, term, family, full=fitted)
            except FAILURES as e:  # the null model of this structure failed, or the pair is degenerate
                step.messages += (f"the test failed: {_reason(e)}",)
                why = "the test failed"
            else:
                step.decision = "kept: not singular, converged" if not fitted.singular else \
                    "kept: converged, singular only in a random intercept (" + ", ".join(_zero(fitted)) + \
                    "), which the rule keeps"
                selection.kept = structure
                return selection
        if structure.correlated:
            step.decision = f"{why}: leave out the correlations"
            structure = Structure(structure.slopes, correlated=False)
            continue
        if fitted is None:  # no variances to rank: the last slope named goes first
            group, slope = [(g, s) for g, slopes in structure.slopes for s in slopes][-1]
            step.decision = f"{why}: leave out the slope of {slope.removeprefix(term)} by {group} (the fit gave " \
                            "no variances; the last slope named)"
        else:
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
