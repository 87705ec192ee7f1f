"""``scenesuggest analyze report``: every table and figure of a study in one folder, with a README that states
the design, N, exclusions, the data's origin and the seed.

Each part is computed on its own: a part that cannot be computed (a measure that cannot be modelled, a
condition without data) leaves a note in the README and the rest of the report still stands.
"""

from __future__ import annotations

from collections.abc import Callable
from datetime import UTC, datetime
from pathlib import Path

import pandas as pd

from scenesuggest.contract.scoring import FORMULA

from . import figures
from .closeness import SCORE_TEST, closeness_table, score_over_time
from .errors import AnalysisError
from .jsonout import dumps
from .load import StudyData
from .measures import TRIAL_MEASURES, participants_table, picks_table, trials_table
from .reproduce import FILE_NAME as REPRODUCE_R
from .reproduce import write_reproduce_r
from .tables import (
    MEASURES,
    Table,
    TestResult,
    condition_tests,
    contrasts_table,
    fit_note,
    selection_table,
    sentences,
    survey_table,
    table1,
    table2,
    tests_table,
)


def select(data: StudyData, completed_only: bool = False, include_pilots: bool = False
           ) -> tuple[pd.DataFrame, pd.DataFrame, pd.DataFrame, list[str], list[str]]:
    """Trials, picks and participants to analyse, the conditions in order, and notes on what was left out.
    By default every completed trial of every participant the experimenter did not exclude is analysed, pilots
    (test runs and simulated participants) only when the data hold nobody else (or ``include_pilots``);
    ``completed_only`` keeps only participants who finished the study."""
    notes = []
    trials = trials_table(data)
    people = participants_table(data)
    pilots = people.loc[people["pilot"], "participant"]
    # the others who count are those who took part (a schedule row, trials), not visitors who only arrived
    others = people.loc[~people["pilot"] & people["participant"].isin(trials["participant"]), "participant"]
    if len(pilots) and not len(others):
        notes.insert(0, PILOTS_ONLY)
    elif len(pilots) and not include_pilots:
        notes.append(f"{len(pilots)} pilot participant(s) (test runs and simulated participants) are left out "
                     "(--include-pilots analyses them too)")
        trials = trials[~trials["participant"].isin(pilots)]
        people = people[~people["pilot"]]
    elif len(pilots):
        notes.append(f"{len(pilots)} pilot participant(s) (test runs and simulated participants) are analysed with "
                     "the others (--include-pilots)")
    if completed_only:
        unfinished = people.loc[~people["status"].isin(["completed", "excluded"]), "participant"]
        dropped = trials["participant"].isin(unfinished)
        if dropped.any():
            notes.append(f"{trials.loc[dropped, 'participant'].nunique()} participant(s) who did not finish the "
                         f"study are left out ({int(dropped.sum())} scheduled trials; --completed-only)")
        trials = trials[~dropped]
    excluded = people.loc[people["status"] == "excluded", "participant"]
    if len(excluded):
        reasons = data.participants.set_index("participant").reindex(excluded)
        why = reasons.get("excluded_reason", pd.Series(dtype=str)).fillna("").tolist()
        notes.append(f"{len(excluded)} participant(s) excluded by the experimenter: "
                     + "; ".join(f"{p} ({w or 'no reason given'})" for p, w in zip(excluded, why, strict=True)))
    trials = trials[~trials["participant"].isin(excluded)]
    conditions = data.conditions
    stated = data.manifest.get("design", {}).get("conditions")
    if stated:
        unknown = trials.loc[~trials["condition"].isin(stated), "condition"]
        if len(unknown):
            notes.append(f"{len(unknown)} trial(s) with a condition the study does not define "
                         f"({', '.join(sorted(map(str, unknown.unique())))}) are left out")
            trials = trials[trials["condition"].isin(stated)]
    for c in conditions:
        if not ((trials["condition"] == c) & trials["complete"]).any():
            notes.append(f"condition {c!r} has no completed trials: its rows say “no data” and it is not modelled")
    incomplete = trials[~trials["complete"]]
    if len(incomplete):
        notes.append(f"{len(incomplete)} scheduled trial(s) were not completed (no “done”) by "
                     f"{incomplete['participant'].nunique()} participant(s); their completed trials are analysed")
    all_picks = picks_table(data, trials)
    picks = all_picks[all_picks["final"]]
    if len(picks) < len(all_picks):
        notes.append(f"{len(all_picks) - len(picks)} pick(s) were replaced in place by another pick (a suggestion "
                     "placed at once, then changed); only the final choice counts for MRR and Table 2")
    unranked = int(picks["rank"].isna().sum())
    if unranked:
        notes.append(f"{unranked} pick(s) without a rank are left out of MRR and Table 2")
    return trials.reset_index(drop=True), picks.reset_index(drop=True), people, conditions, notes


#: The note (first in the README) on data that hold pilots only.
PILOTS_ONLY = ("every participant is a pilot (a test run or a simulated participant): this report is of pilot data, "
               "for checking the study and its analysis, not of the study's participants")


def _design_text(data: StudyData, conditions: list[str]) -> list[str]:
    design = data.manifest.get("design", {})
    lines = [f"- Conditions (reference first): {', '.join(conditions)}."]
    if design:
        lines.append(f"- Design: {design.get('kind', '?')} ordering of conditions, {design.get('blocking', '?')} "
                     f"blocking, {design.get('rows', '?')} schedule rows; periods (scenes): "
                     + "; ".join(", ".join(p) for p in design.get("periods", [])) + ".")
    return lines


def _write_measures(out: Path, trials: pd.DataFrame, picks: pd.DataFrame, people: pd.DataFrame) -> Path:
    """Write the per-trial, per-pick and per-participant measures as CSV into ``out/measures``; returns that folder."""
    measures_dir = out / "measures"
    measures_dir.mkdir(exist_ok=True)
    trials.to_csv(measures_dir / "trials.csv", index=False)
    picks.to_csv(measures_dir / "picks.csv", index=False)
    people.to_csv(measures_dir / "participants.csv", index=False)
    return measures_dir


def _tables_and_tests(out: Path, trials: pd.DataFrame, picks: pd.DataFrame, people: pd.DataFrame,
                      conditions: list[str], notes: list[str], resamples: int, seed: int, unit: str,
                      progress: Callable[[str], None]) -> tuple[list[Table], Table | None, list[TestResult]]:
    """(tables, closeness table or None, tests) written into ``out/tables`` and ``out``, what failed added to notes."""
    tables: list[Table] = [table1(trials, picks, conditions, resamples, seed, unit), table2(picks, conditions)]
    close = closeness_table(trials, conditions, resamples, seed, unit)
    scored = close is not None
    if scored:
        tables.append(close)
    else:
        notes.append("how close to the target: the data has no scores (an export made before trials were scored)")
    modelled = MEASURES + ([SCORE_TEST] if scored else [])
    results = condition_tests(trials, picks, conditions, progress, modelled)
    try:
        write_reproduce_r(out, modelled, conditions, [_random_part(r, conditions) for r in results])
    except AnalysisError as e:
        notes.append(f"{REPRODUCE_R}: not written — {e}")
    tables += [tests_table(results), selection_table(results), contrasts_table(results), survey_table(people)]
    for r in results:
        if r.error:
            notes.append(f"{r.label}: not modelled — {r.error}")
    for t in tables:
        for ext, text in (("md", t.markdown()), ("tex", t.latex()), ("csv", t.csv())):
            (out / "tables" / f"{t.name}.{ext}").write_text(text, encoding="utf-8")
    return tables, close, results


def _random_part(r: TestResult, conditions: list[str]) -> str:
    """The random part of lme4's formula for a measure's models, as reproduce.R names the condition's dummies
    (``.condition2`` for the second condition, whatever its name): "" for a measure that is not modelled."""
    if r.selection is None or r.selection.kept is None:
        return ""
    columns = {f"condition{c}": f".condition{k}" for k, c in enumerate(conditions, 1)}
    return r.selection.kept.lme4(columns.__getitem__)


def _figures(out: Path, trials: pd.DataFrame, done: pd.DataFrame, picks: pd.DataFrame, over_time: pd.DataFrame,
             conditions: list[str], notes: list[str]) -> list[Path]:
    """The figure files written into ``out/figures``; a figure without data is a note instead."""
    figure_files = []
    for make, frame in ((figures.time_by_scene, trials), (figures.rank_distribution, picks),
                        (figures.learning_curves, trials), (figures.closeness_over_time, over_time)):
        if frame is picks and picks.dropna(subset=["rank"]).empty or frame is trials and done.empty \
                or frame is over_time and over_time.empty:
            notes.append(f"figure {make.__name__}: no data")
            continue
        figure_files += make(frame, conditions, out / "figures")
    return figure_files


def build_report(data: StudyData, out: str | Path, *, resamples: int = 1000, seed: int = 0, unit: str = "trial",
                 completed_only: bool = False, include_pilots: bool = False,
                 progress: Callable[[str], None] = lambda label: None) -> dict:
    """Write the report into ``out``; returns its machine-readable summary (also ``results.json``)."""
    out = Path(out)
    (out / "tables").mkdir(parents=True, exist_ok=True)
    progress("measures")
    trials, picks, people, conditions, notes = select(data, completed_only, include_pilots)
    done = trials[trials["complete"]]
    measures_dir = _write_measures(out, trials, picks, people)

    progress("bootstrap intervals")
    tables, close, results = _tables_and_tests(out, trials, picks, people, conditions, notes, resamples, seed, unit,
                                               progress)

    progress("score over time")
    over_time, time_notes = score_over_time(data, trials)
    notes += time_notes
    over_time.to_csv(measures_dir / "score_over_time.csv", index=False)

    progress("figures")
    figure_files = _figures(out, trials, done, picks, over_time, conditions, notes)

    people_analysed = done["participant"].nunique()
    summary = {
        "study": data.manifest.get("study"), "source": data.manifest.get("source"),
        "study_hash": data.manifest.get("study_hash"), "code_version": data.manifest.get("code_version"),
        "exported_at": data.manifest.get("exported_at"), "generated_at": datetime.now(UTC).isoformat(),
        "seed": seed, "resamples": resamples, "unit": unit, "conditions": conditions,
        "participants": {"total": len(data.participants),
                         "completed": int((people["status"] == "completed").sum()),
                         "pilot": int(data.participants["pilot"].sum()),
                         "analysed": int(people_analysed)},
        "trials": {"scheduled": len(trials), "completed": len(done)}, "picks": len(picks), "notes": notes,
        "table1": tables[0].data, "table2": tables[1].data, "closeness": close.data if close is not None else None,
        "tests": {r.measure: (r.comparison.to_dict() | {"contrasts": [c.to_dict() for c in r.contrasts]}
                              if r.comparison else {"error": r.error}) | {"modelled": r.comparison is not None,
                                                                         "note": fit_note(r)}
                  | ({"selection": r.selection.to_dict()} if r.selection else {}) for r in results},
        "intercepts_only": sentences(results),
    }
    (out / "results.json").write_text(dumps(summary))
    progress("README")
    (out / "README.md").write_text(_readme(data, summary, tables, figure_files, out, conditions), encoding="utf-8")
    return summary


def _readme(data, summary, tables, figure_files, out, conditions) -> str:
    p, t = summary["participants"], summary["trials"]
    m = data.manifest
    lines = [f"# Analysis report: {m.get('title') or m.get('study') or 'study'}", "",
             *([f"**Pilot data only:** {PILOTS_ONLY}.", ""] if PILOTS_ONLY in summary["notes"] else []),
             f"Generated {summary['generated_at']} by `scenesuggest analyze report`.", "", "## Data", "",
             f"- Source: `{m.get('source')}`" + (f", exported {m['exported_at']}" if m.get("exported_at") else "")
             + (f" by SceneSuggest {m['code_version']}" if m.get("code_version") else "") + ".",
             f"- Study: `{m.get('study')}`, study file sha256 `{m.get('study_hash')}`.",
             *_design_text(data, conditions),
             f"- N: {p['total']} participants arrived" + (f" ({p['pilot']} of them pilots)" if p['pilot'] else "")
             + f", {p['completed']} completed, "
             f"{p['analysed']} contributed completed trials; {t['completed']} of {t['scheduled']} scheduled trials "
             f"completed; {summary['picks']} picks.",
             f"- Bootstrap: {summary['resamples']} percentile resamples of {summary['unit']}s, seed "
             f"{summary['seed']}.", "", "## Exclusions and notes", ""]
    lines += [f"- {n}" for n in summary["notes"]] or ["- none"]
    lines += ["", "## Measures", ""] + [f"- `{k}`: {v}" for k, v in TRIAL_MEASURES.items()]
    lines += ["- MRR: mean of 1 / rank over every final pick with a rank (fixed list, search results or "
              "suggestions); a pick replaced in place by another (`final` false in `picks.csv`) does not count.",
              f"- `score` (how close to the target): {FORMULA}.",
              "", "## Tables", ""]
    for table in tables:
        lines += [table.markdown(), f"Also as `tables/{table.name}.tex` (booktabs) and `tables/{table.name}.csv`.",
                  ""]
        if table.name == "random_effects" and summary["intercepts_only"]:
            lines += ["Would random intercepts alone have changed a conclusion?", ""]
            lines += [f"- {s}" for s in summary["intercepts_only"]] + [""]
    lines += ["## Figures", ""]
    lines += [f"![{f.stem}]({f.relative_to(out).as_posix()})" for f in figure_files if f.suffix == ".png"]
    lines += ["", "Each figure is also an SVG beside its PNG. Per-trial, per-pick and per-participant measures are "
                  "in `measures/`; every number above is in `results.json`.", "",
              "## In R", "",
              f"`Rscript {REPRODUCE_R}` (R with lme4) fits the likelihood-ratio tests' models again with lme4 from "
              "`measures/`, each with the random effects chosen above, and prints each test and every fixed effect "
              "with its standard error, in the order above.",
              ""]
    return "\n".join(lines)
