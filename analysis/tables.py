"""The paper's tables from trial and pick measures, each renderable as Markdown, LaTeX (booktabs) and CSV.

- Table 1: per condition, mean total / rotation / translation time, translation distance, model queries and
  MRR, each with a 95% percentile bootstrap interval.
- Table 2: the distribution of chosen ranks (1, 2, 3, 4+) per condition.
- Likelihood-ratio tests of condition for every Table 1 measure (linear mixed models; Poisson for counts) under
  the random effects chosen for it (:mod:`analysis.selection`, every step in its own table), Holm-corrected pairwise
  contrasts; Likert means and preference counts.
"""

from __future__ import annotations

import csv
import io
from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from .bootstrap import bootstrap_by
from .convergence import SINGULAR
from .errors import AnalysisError
from .mixed import pairwise
from .results import Comparison, format_p
from .selection import Selection, choose

#: (column, label, digits, family, table) — what Table 1 and the tests cover; ``picks`` rows for MRR.
MEASURES = [
    ("total_time", "Total time (s)", 1, "gaussian", "trials"),
    ("rotation_time", "Rotation time (s)", 1, "gaussian", "trials"),
    ("translation_time", "Translation time (s)", 1, "gaussian", "trials"),
    ("translation_distance", "Translation distance (m)", 2, "gaussian", "trials"),
    ("n_queries", "Model queries", 2, "poisson", "trials"),
    ("reciprocal_rank", "MRR", 3, "gaussian", "picks"),
]
RANK_BINS = ("1", "2", "3", "4+")


@dataclass
class Table:
    """A rendered table: ``rows`` are display strings, ``data`` the same content as numbers for CSV."""

    name: str
    title: str
    caption: str
    columns: list[str]
    rows: list[list[str]]
    data: list[dict] = field(default_factory=list)

    def markdown(self) -> str:
        lines = [f"**{self.title}.** {self.caption}", "", "| " + " | ".join(self.columns) + " |",
                 "|" + "|".join(["---"] + ["---:"] * (len(self.columns) - 1)) + "|"]
        lines += ["| " + " | ".join(_cell(c) for c in r) + " |" for r in self.rows]
        return "\n".join(lines) + "\n"

    def latex(self) -> str:
        spec = "l" + "r" * (len(self.columns) - 1)
        body = [" & ".join(_tex(c) for c in r) + r" \\" for r in self.rows]
        return "\n".join([r"\begin{table}", r"\centering", rf"\caption{{{_tex(self.title)}. {_tex(self.caption)}}}",
                          rf"\label{{tab:{self.name}}}", rf"\begin{{tabular}}{{{spec}}}", r"\toprule",
                          " & ".join(_tex(c) for c in self.columns) + r" \\", r"\midrule", *body, r"\bottomrule",
                          r"\end{tabular}", r"\end{table}"]) + "\n"

    def csv(self) -> str:
        buf = io.StringIO()
        if self.data:
            w = csv.DictWriter(buf, fieldnames=list(self.data[0]), lineterminator="\n")
            w.writeheader()
            w.writerows(self.data)
        return buf.getvalue()


def _cell(text: str) -> str:
    """A Markdown table cell: a pipe escaped, a line break (lme4's messages have them) a space."""
    return " ".join(str(text).split("\n")).replace("|", "\\|")


_TEX = {"\\": r"\textbackslash{}", "&": r"\&", "%": r"\%", "$": r"\$", "#": r"\#", "_": r"\_", "{": r"\{",
        "}": r"\}", "~": r"\textasciitilde{}", "^": r"\textasciicircum{}", "−": "--", "–": "--", "<": r"$<$",
        ">": r"$>$", "“": "``", "”": "''"}


def _tex(text: str) -> str:
    """LaTeX-escape a cell (χ² becomes math)."""
    return "".join(_TEX.get(ch, ch) for ch in str(text)).replace("χ²", r"$\chi^2$")


def _frame(trials: pd.DataFrame, picks: pd.DataFrame, table: str) -> pd.DataFrame:
    return picks if table == "picks" else trials[trials["complete"]]


def table1(trials: pd.DataFrame, picks: pd.DataFrame, conditions: list[str], resamples: int = 1000,
           seed: int = 0, unit: str = "trial") -> Table:
    """Means with 95% bootstrap intervals per condition (seeded; one generator per measure)."""
    stats = {m: bootstrap_by(_frame(trials, picks, t), m, "condition", conditions, unit, resamples, seed,
                             empty_ok=True) for m, _, _, _, t in MEASURES}
    rows, data = [], []
    for c in conditions:
        n = int(((trials["condition"] == c) & trials["complete"]).sum())
        rows.append([c, str(n)] + [stats[m][c].text(d) for m, _, d, _, _ in MEASURES])
        record = {"condition": c, "trials": n}
        for m, _, _, _, _ in MEASURES:
            iv = stats[m][c]
            record |= {f"{m}_mean": iv.mean, f"{m}_low": iv.low, f"{m}_high": iv.high, f"{m}_n": iv.n}
        data.append(record)
    what = "participants (all of a participant's trials together)" if unit == "participant" else "trials"
    caption = (f"Means per condition with 95% percentile bootstrap intervals from {resamples} resamples of "
               f"{what}, seed {seed}. MRR is the mean reciprocal rank of chosen models over all picks.")
    return Table("table1", "Table 1: time, queries and MRR by condition", caption,
                 ["Condition", "Trials"] + [label for _, label, _, _, _ in MEASURES], rows, data)


def table2(picks: pd.DataFrame, conditions: list[str]) -> Table:
    """How often the chosen model was 1st, 2nd, 3rd or lower in the list it was picked from."""
    rows, data = [], []
    ranked = picks.dropna(subset=["rank"])
    for c in conditions:
        r = ranked.loc[ranked["condition"] == c, "rank"]
        counts = [int((r == 1).sum()), int((r == 2).sum()), int((r == 3).sum()), int((r >= 4).sum())]
        total = sum(counts)
        shares = [k / total if total else float("nan") for k in counts]
        rows.append([c, str(total)] + [f"{k} ({s:.1%})" if total else "–" for k, s in zip(counts, shares,
                                                                                          strict=True)])
        data.append({"condition": c, "picks": total, **{f"rank_{b}": k for b, k in zip(RANK_BINS, counts,
                                                                                           strict=True)},
                     **{f"share_{b}": s for b, s in zip(RANK_BINS, shares, strict=True)}})
    return Table("table2", "Table 2: rank of the chosen model", "Picks by their rank in the list they were "
                 "chosen from (fixed list, search results or context suggestions); share of the condition's picks.",
                 ["Condition", "Picks", "Rank 1", "Rank 2", "Rank 3", "Rank 4+"], rows, data)


def random_terms(frame: pd.DataFrame) -> list[str]:
    """Crossed random intercepts for participant and scene, leaving out a factor with a single level."""
    return [g for g in ("participant", "scene") if frame[g].nunique() > 1]


@dataclass
class TestResult:
    """A measure's test of condition: ``selection`` holds the structures tried (:mod:`analysis.selection`),
    ``comparison`` the test under the one kept; ``error`` says why a measure is not modelled."""

    measure: str
    label: str
    family: str
    comparison: Comparison | None = None
    contrasts: list = field(default_factory=list)
    error: str = ""
    selection: Selection | None = None


def condition_tests(trials: pd.DataFrame, picks: pd.DataFrame, conditions: list[str],
                    progress=lambda label: None, measures=None) -> list[TestResult]:
    """Per measure (default: :data:`MEASURES`): the random effects chosen by :func:`analysis.selection.choose`,
    the model with and without condition under them, the LR test, and pairwise contrasts. A measure that cannot
    be modelled keeps its error message instead."""
    out = []
    for m, label, _, family, table in measures or MEASURES:
        progress(f"model of {m}")
        frame = _frame(trials, picks, table)
        frame = frame[frame["condition"].isin(conditions)].dropna(subset=[m]).copy()
        frame["condition"] = pd.Categorical(frame["condition"], conditions)
        result = TestResult(m, label, family)
        try:
            present = [c for c in conditions if (frame["condition"] == c).any()]
            result.selection = choose(frame, m, family)
            result.comparison = result.selection.comparison
            result.contrasts = pairwise(result.comparison.full, "condition", present)
        except AnalysisError as e:  # (the row names the measure: the message is the reason)
            result.error = e.message
        except (np.linalg.LinAlgError, ValueError, FloatingPointError) as e:
            result.error = f"the model could not be fitted ({e})"
        out.append(result)
    return out


def _model_name(family: str) -> str:
    return "LMM" if family == "gaussian" else "Poisson GLMM"


def fit_note(r: TestResult) -> str:
    """What a reader must know beside a measure's numbers: why it is not modelled, or lme4's messages on the fit
    kept (a singular fit in lme4's words)."""
    if r.comparison is None:
        return f"not modelled: {r.error}"
    return "; ".join(r.comparison.full.messages)


def _kept(r: TestResult) -> str:
    return r.selection.kept.name() if r.selection and r.selection.kept else "intercepts only"


def tests_table(results: list[TestResult]) -> Table:
    rows, data = [], []
    for r in results:
        if r.comparison is None:
            rows.append([r.label, _model_name(r.family), "–", "–", "–", "–", fit_note(r)])
            data.append({"measure": r.measure, "family": r.family, "random": "", "chi2": "", "df": "", "n": "",
                         "p": "", "loglik_full": "", "loglik_null": "", "singular": "", "intercepts_only_chi2": "",
                         "intercepts_only_p": "", "modelled": False, "note": fit_note(r)})
            continue
        t, t0 = r.comparison.lrt, r.selection.intercepts.lrt
        rows.append([r.label, _model_name(r.family), _kept(r), f"χ²({t.df}, N = {t.nobs}) = {t.chi2:.2f}",
                     format_p(t.p), f"χ²({t0.df}) = {t0.chi2:.2f}, {format_p(t0.p)}", fit_note(r)])
        data.append({"measure": r.measure, "family": r.family, "random": _kept(r), "chi2": t.chi2, "df": t.df,
                     "n": t.nobs, "p": t.p, "loglik_full": t.full_loglik, "loglik_null": t.null_loglik,
                     "singular": r.comparison.full.singular, "intercepts_only_chi2": t0.chi2,
                     "intercepts_only_p": t0.p, "modelled": True, "note": fit_note(r)})
    return Table("lr_tests", "Likelihood-ratio tests of condition", "Maximum-likelihood mixed models with and "
                 "without condition, with the random effects chosen for each measure (table “Random effects chosen”: "
                 "random slopes of condition by participant and by scene where the data support them, else crossed "
                 "random intercepts); Poisson with log link for counts, reciprocal ranks per pick. Beside each test, "
                 "the same test with random intercepts only. A measure the data cannot inform a test of (no variance "
                 "within a condition, a count that is zero throughout one, a degenerate fit) is not modelled, and "
                 f"says why; the note gives lme4's messages on the fit, “{SINGULAR}” where a variance is estimated at "
                 "zero or a correlation at ±1 (isSingular).",
                 ["Measure", "Model", "Random effects", "Test", "p", "Intercepts only", "Note"], rows, data)


def selection_table(results: list[TestResult]) -> Table:
    """Every random-effects structure tried, per measure, and what was done next and why."""
    rows, data = [], []
    for r in results:
        if r.selection is None:
            continue
        for k, step in enumerate(r.selection.steps, 1):
            formula = step.formula[step.formula.index("("):] if step.formula else "–"  # the random part
            fitted = step.status in ("singular", "not singular")
            rows.append([r.label, str(k), step.structure, formula, step.status if fitted or step.failed else "–",
                         "; ".join(step.messages) or "–", step.decision])
            data.append({"measure": r.measure, "step": k, "structure": step.structure, "formula": step.formula,
                         "singular": step.singular if fitted else "", "messages": "; ".join(step.messages),
                         "decision": step.decision})
    return Table("random_effects", "Random effects chosen", "For each measure, from the maximal structure the design "
                 "supports (correlated random slopes of condition by participant and by scene) towards random "
                 "intercepts: while a fit is singular or does not converge, leave out the correlations, then the "
                 "random slope with the smallest variance, one at a time (Barr et al. 2013; Bates et al. 2015; "
                 "Matuschek et al. 2017 simplify by likelihood-ratio tests or AIC instead). Random intercepts are "
                 "never left out. The last step of each measure is the structure its test uses. Messages are lme4's "
                 "on the fit, or why a structure could not be fitted or tested.",
                 ["Measure", "Step", "Structure", "Formula", "Fit", "Messages", "Decision"], rows, data)


def sentences(results: list[TestResult]) -> list[str]:
    """Per modelled measure: whether random intercepts alone would have changed the conclusion."""
    return [f"{r.label}: {r.selection.sentence()}" for r in results if r.comparison is not None and r.selection]


def contrasts_table(results: list[TestResult]) -> Table:
    rows, data = [], []
    for r in results:
        if r.comparison is None:
            rows.append([r.label, "–", "–", "–", "–", "–", "–", fit_note(r)])
            data.append({"measure": r.measure, "contrast": "", "estimate": "", "se": "", "z": "", "p": "",
                         "p_holm": "", "note": fit_note(r)})
        for c in r.contrasts:
            scale = " (log rate)" if r.family == "poisson" else ""
            rows.append([r.label, f"{c.a} − {c.b}", f"{c.estimate:.3g}{scale}", f"{c.se:.3g}", f"{c.z:.2f}",
                         format_p(c.p), format_p(c.p_holm), fit_note(r)])
            data.append({"measure": r.measure, **c.to_dict(), "note": fit_note(r)})
    return Table("contrasts", "Pairwise contrasts between conditions", "Wald z tests from the full model; "
                 "p-values Holm-corrected over the three contrasts of each measure. A measure that is not modelled "
                 "has no contrasts: its row says why.",
                 ["Measure", "Contrast", "Estimate", "SE", "z", "p", "p (Holm)", "Note"], rows, data)


def survey_table(participants: pd.DataFrame) -> Table:
    """Exit-survey answers: numeric (Likert) items as mean, SD and n; choice items as counts."""
    rows, data = [], []
    for column in [c for c in participants.columns if str(c).startswith("exit.")]:
        values = participants[column].dropna()
        if values.empty:
            continue
        question = column.removeprefix("exit.")
        if pd.api.types.is_numeric_dtype(values):
            rows.append([question, f"{values.mean():.2f}", f"{values.std(ddof=1):.2f}" if len(values) > 1 else "–",
                         str(len(values))])
            data.append({"question": question, "answer": "", "mean": values.mean(), "sd": values.std(ddof=1),
                         "n": len(values)})
        else:
            for answer, n in values.astype(str).value_counts().items():
                rows.append([question, f"“{answer}”", "", str(n)])
                data.append({"question": question, "answer": answer, "mean": "", "sd": "", "n": int(n)})
    return Table("survey", "Exit survey", "Likert items: mean and standard deviation; choices: counts.",
                 ["Question", "Mean / answer", "SD", "n"], rows, data)
