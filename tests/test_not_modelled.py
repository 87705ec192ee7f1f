"""A report never claims what it could not model: a measure at a ceiling or a floor, or whose fit is degenerate, is
named as not modelled with the reason — in the LR tests, the contrasts, the README and results.json — and
reproduce.R names the same measures for the same reasons; a singular fit is marked in the tables."""

from __future__ import annotations

import dataclasses
import subprocess

import numpy as np
import pandas as pd
import pytest
from demostudy import make_app
from support import require_lme4
from test_reproduce_r import printed

from analysis import AnalysisError, tables
from analysis.degenerate import NotModelled, check_fit
from analysis.design import build_design
from analysis.load import read_database
from analysis.mixed import compare
from analysis.report import build_report
from analysis.reproduce import write_reproduce_r
from analysis.tables import MEASURES, SINGULAR, condition_tests, contrasts_table
from simulation.run import simulate

CONDITIONS = ["none", "basic", "full"]


def _frames(seed: int = 4) -> tuple[pd.DataFrame, pd.DataFrame]:
    """Trials and picks of 6 participants × 3 scenes × 3 conditions, one measure for each way a test can be
    uninformative: rotation time at a floor in `full`, translation time an exact sum of condition, participant and
    scene, translation distance constant, no query at all in `full`; total time and MRR ordinary."""
    rng = np.random.default_rng(seed)
    rows = []
    for p in range(6):
        for s in range(3):
            for c, condition in enumerate(CONDITIONS):
                rows.append({"participant": f"P{p}", "scene": f"S{s}", "condition": condition, "complete": True,
                             "total_time": 100 - 15 * c + rng.normal(0, 10) + 5 * p,
                             "rotation_time": 0.0 if condition == "full" else rng.gamma(2, 5),
                             "translation_time": 10.0 + 2.0 * c + 0.5 * p + 0.25 * s,
                             "translation_distance": 1.5,
                             "n_queries": 0 if condition == "full" else int(rng.poisson(3))})
    trials = pd.DataFrame(rows)
    picks = trials[["participant", "scene", "condition"]].loc[trials.index.repeat(2)].reset_index(drop=True)
    picks["reciprocal_rank"] = 1.0 / rng.integers(1, 4, len(picks))
    return trials, picks


REASONS = {
    "rotation_time": "has no variance within a level of condition (every value in full is 0): a ceiling or a floor, "
                     "which a linear model with one residual variance cannot describe",
    "translation_time": "the model reproduces every value exactly (no residual variance): its standard errors are "
                        "rounding noise",
    "translation_distance": "is constant; there is no variance to model",
    "n_queries": "is zero in every row of full: its log rate there has no finite estimate (a floor)",
}


def test_each_uninformative_measure_is_named_with_its_reason_and_gets_no_contrast():
    trials, picks = _frames()
    results = condition_tests(trials, picks, CONDITIONS)
    errors = {r.measure: r.error for r in results if r.error}
    assert errors == REASONS
    assert all(r.contrasts for r in results if not r.error)  # the rest are tested and contrasted
    contrasts = contrasts_table(results)
    for r in results:
        lines = [row for row in contrasts.rows if row[0] == r.label]
        if r.error:  # one row, no number in it: the reason
            assert lines == [[r.label, "–", "–", "–", "–", "–", "–", f"not modelled: {r.error}"]]
        else:
            assert len(lines) == 3 and all(row[2] != "–" for row in lines)
    tests = {row[0]: row for row in tables.tests_table(results).rows}
    for r in results:
        assert (tests[r.label][3] == "–") == bool(r.error)  # the Test column
        if r.error:
            assert tests[r.label][-1] == f"not modelled: {r.error}"


def test_reproduce_r_names_the_same_measures_for_the_same_reasons(tmp_path):
    rscript = require_lme4()
    trials, picks = _frames()
    (tmp_path / "measures").mkdir()
    trials.to_csv(tmp_path / "measures" / "trials.csv", index=False)
    picks.to_csv(tmp_path / "measures" / "picks.csv", index=False)
    script = write_reproduce_r(tmp_path, MEASURES, CONDITIONS)
    ran = subprocess.run([rscript, str(script)], capture_output=True, text=True, timeout=300)
    assert ran.returncode == 0, ran.stderr
    tests, not_modelled, _ = printed(ran.stdout)
    assert not_modelled == REASONS
    assert set(tests) == {"total_time", "reciprocal_rank"}


@pytest.fixture(scope="module")
def ceiling_pilot(tmp_path_factory, demo_resources):
    """Two simulated participants on the demo whose `basic` and `full` trials all scored 1 (the score's ceiling)
    while `none`'s did not: the pilot a new experimenter ran."""
    folder = tmp_path_factory.mktemp("pilot")
    app = make_app(folder / "server")
    assert simulate(2, seed=3, study="demo", app=app)["completed"] == 2
    data = read_database(app.config["SQLALCHEMY_DATABASE_URI"])
    trials = data.trials
    main = trials["kind"] == "trial"
    trials.loc[main & trials["condition"].isin(["basic", "full"]), "score"] = 1.0
    none = main & (trials["condition"] == "none")
    trials.loc[none, "score"] = np.linspace(0.55, 0.8, int(none.sum()))
    return data, folder


def test_the_ceiling_pilots_report_prints_no_contrast_for_the_score(ceiling_pilot, tmp_path):
    data, _ = ceiling_pilot
    report = build_report(data, tmp_path / "report", resamples=20)
    why = ("has no variance within a level of condition (every value in basic is 1; every value in full is 1): a "
           "ceiling or a floor, which a linear model with one residual variance cannot describe")
    score = report["tests"]["score"]
    assert score == {"error": why, "modelled": False, "note": f"not modelled: {why}"}
    contrasts = (tmp_path / "report" / "tables" / "contrasts.md").read_text()
    score_rows = [line for line in contrasts.splitlines() if line.startswith("| Score")]
    assert score_rows == [f"| Score (0–1) | – | – | – | – | – | – | not modelled: {why} |"]
    csv = pd.read_csv(tmp_path / "report" / "tables" / "contrasts.csv")
    assert csv.loc[csv["measure"] == "score", "estimate"].isna().all()
    lr = pd.read_csv(tmp_path / "report" / "tables" / "lr_tests.csv").set_index("measure")
    assert not lr.loc["score", "modelled"] and pd.isna(lr.loc["score", "chi2"])
    assert f"Score (0–1): not modelled — {why}" in (tmp_path / "report" / "README.md").read_text()


def test_singular_fits_are_marked_in_the_reports_tables(ceiling_pilot, tmp_path):
    data, _ = ceiling_pilot
    report = build_report(data, tmp_path / "report", resamples=20)
    singular = {m for m, t in report["tests"].items() if t["modelled"] and t["singular"]}
    assert singular  # two participants: some variance is estimated at zero
    lr = pd.read_csv(tmp_path / "report" / "tables" / "lr_tests.csv").set_index("measure")
    for measure, test in report["tests"].items():
        if test["modelled"]:
            assert (SINGULAR in str(lr.loc[measure, "note"])) == test["singular"], measure
            assert test["note"] == "; ".join(test["messages"])
            assert (SINGULAR in test["messages"]) == test["singular"]
    label = {m: label for m, label, *_ in MEASURES}
    text = (tmp_path / "report" / "tables" / "lr_tests.md").read_text()
    for measure in singular:
        row = next(line for line in text.splitlines() if line.startswith(f"| {label[measure]} |"))
        assert row.endswith(f"| {SINGULAR} |") or f"| {SINGULAR}; " in row


def test_a_fit_below_its_null_is_not_modelled():
    trials, _ = _frames()
    frame = trials.assign(condition=pd.Categorical(trials["condition"], CONDITIONS))
    design = build_design(frame, "total_time", ["condition"], ["participant", "scene"])
    good = compare(design, "condition")
    check_fit(design, good)
    worse = dataclasses.replace(good, full=dataclasses.replace(good.full, loglik=good.null.loglik - 0.01))
    with pytest.raises(NotModelled, match="lower log-likelihood"):
        check_fit(design, worse)
    nan = dataclasses.replace(good, full=dataclasses.replace(good.full, se={**good.full.se,
                                                                             "conditionfull": float("nan")}))
    with pytest.raises(NotModelled, match="not a finite positive number"):
        check_fit(design, nan)


def test_analyze_lmm_refuses_a_degenerate_model_naming_why(tmp_path):
    from click.testing import CliRunner

    from scenesuggest.cli import main

    trials, _ = _frames()
    trials.to_csv(tmp_path / "t.csv", index=False)
    run = CliRunner().invoke(main, ["analyze", "lmm", str(tmp_path / "t.csv"), "--response", "rotation_time",
                                    "--fixed", "condition", "--random", "participant", "--random", "scene"])
    assert run.exit_code == 2
    assert "response 'rotation_time': has no variance within a level of condition (every value in full is 0)" \
        in run.output and "Traceback" not in run.output
    with pytest.raises(AnalysisError):
        compare(build_design(trials, "n_queries", ["condition"], ["participant"]), "condition", "poisson")


def test_r_and_the_report_refuse_too_little_data_in_the_same_words(tmp_path):
    """Before the rule, the model matrices refuse a measure with data in one condition only, or in fewer than three
    rows: reproduce.R says the same, in the same order."""
    rscript = require_lme4()
    trials, picks = _frames()
    trials.loc[trials["condition"] != "none", "total_time"] = np.nan  # one condition with data
    trials.loc[~trials.index.isin([0, 13]), "translation_time"] = np.nan  # two rows (two people, two scenes)
    results = {r.measure: r.error for r in condition_tests(trials, picks, CONDITIONS)}
    assert results["total_time"] == "'condition' has 1 level(s) with data; a fixed effect needs at least 2"
    assert results["translation_time"] == "only 2 complete row(s)"
    (tmp_path / "measures").mkdir()
    trials.to_csv(tmp_path / "measures" / "trials.csv", index=False)
    picks.to_csv(tmp_path / "measures" / "picks.csv", index=False)
    ran = subprocess.run([rscript, str(write_reproduce_r(tmp_path, MEASURES, CONDITIONS))], capture_output=True,
                         text=True, timeout=300)
    assert ran.returncode == 0, ran.stderr
    _, not_modelled, _ = printed(ran.stdout)
    assert not_modelled == {m: e for m, e in results.items() if e}
