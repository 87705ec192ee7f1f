"""The analysis package: measures from events, bootstrap intervals, tables, figures, the report and its CLI."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import numpy as np
import pandas as pd
import pytest
from scipy import stats
from support import SHARED_DATA, require

from analysis import AnalysisError
from analysis.bootstrap import bootstrap_by, bootstrap_mean
from analysis.load import read_database, read_export
from analysis.measures import picks_table, text_queries, trial_measures, trials_table
from analysis.report import build_report
from analysis.synthetic import write_export
from analysis.tables import table1, table2
from simulation.participant import Bot
from simulation.transport import FlaskTransport


def _events(rows):
    return pd.DataFrame([{"type": k, "client_t_ms": t, "payload": p} for k, t, p in rows])


def test_trial_measures_from_a_hand_made_log():
    ev = _events([
        ("trial_start", 0, {}),
        ("search", 1000, {"text": "so"}), ("search", 1300, {"text": "sofa"}), ("search", 1600, {"text": "sof"}),
        ("insert", 2000, {"object": "a", "rank": 2, "source": "search"}),
        ("search", 2500, {"text": "lamp"}), ("search", 2900, {"text": "table"}),
        ("context_query", 3000, {}), ("insert", 3500, {"object": "b", "rank": 1, "source": "context"}),
        ("replace", 3600, {"object": "c", "rank": 3, "source": "context"}),
        ("move_start", 4000, {"object": "a"}), ("move_end", 6500, {"object": "a", "distance": 1.5}),
        ("rotate_start", 7000, {"object": "c"}), ("move_start", 7100, {"object": "b"}),
        ("move_end", 7600, {"object": "b", "distance": 0.25}), ("rotate_end", 9000, {"object": "c", "angle": 90}),
        ("rotate_end", 9500, {"object": "zz", "angle": 5}),  # never started: ignored
        ("visibility", 10000, {"state": "hidden"}), ("visibility", 40000, {"state": "visible"}),
        ("trial_done", 50000, {}),
    ])
    m = trial_measures(ev)
    assert m["total_time"] == 50.0
    assert m["active_time"] == 20.0
    assert m["translation_time"] == pytest.approx(3.0)
    assert m["rotation_time"] == pytest.approx(2.0)
    assert m["translation_distance"] == pytest.approx(1.75)
    assert m["n_text_queries"] == 3  # "so"→"sofa"→"sof" is one; "lamp" and "table" two more
    assert m["n_context_queries"] == 1 and m["n_queries"] == 4
    assert m["objects_inserted"] == 2 and m["n_picks"] == 3


def test_a_tab_still_hidden_at_done_counts_until_done_and_a_pick_starts_a_new_query():
    ev = _events([("trial_start", 0, {}), ("visibility", 1000, {"state": "hidden"}), ("trial_done", 4000, {})])
    assert trial_measures(ev)["active_time"] == pytest.approx(1.0)
    assert text_queries(_events([("search", 0, {"text": "mug"}), ("insert", 1, {}),
                                 ("search", 2, {"text": "mug"}), ("search", 3, {"text": ""}),
                                 ("search", 4, {"text": "mug"})])) == 3


@pytest.fixture(scope="module")
def synthetic(tmp_path_factory):
    return write_export(tmp_path_factory.mktemp("export"), participants=12, seed=3, drop_last_trial=1)


def test_trials_table_leaves_out_practice_and_marks_incomplete_trials(synthetic):
    data = read_export(synthetic)
    trials = trials_table(data)
    assert len(trials) == 12 * 9 and (trials["kind"] == "trial").all()
    assert (~trials["complete"]).sum() == 1 and trials.loc[~trials["complete"], "total_time"].isna().all()
    assert trials["total_time"].dropna().gt(0).all()


def test_bootstrap_is_seeded_and_agrees_with_scipy_on_plain_means():
    rng = np.random.default_rng(0)
    x = rng.lognormal(5, 0.4, 200)
    a = bootstrap_mean(x, None, np.random.default_rng(1), 4000)
    b = bootstrap_mean(x, None, np.random.default_rng(1), 4000)
    assert a == b and a.mean == pytest.approx(x.mean()) and a.n == 200
    ref = stats.bootstrap((x,), np.mean, n_resamples=4000, method="percentile", rng=np.random.default_rng(2))
    width = ref.confidence_interval.high - ref.confidence_interval.low
    assert a.low == pytest.approx(ref.confidence_interval.low, abs=0.05 * width)
    assert a.high == pytest.approx(ref.confidence_interval.high, abs=0.05 * width)


def test_resampling_participants_gives_wider_intervals_on_clustered_data():
    rng = np.random.default_rng(5)
    people = np.repeat(np.arange(20), 9)
    values = rng.normal(0, 1, 20)[people] + rng.normal(0, 0.5, len(people))
    frame = pd.DataFrame({"participant": people, "trial": np.tile(np.arange(9), 20), "v": values, "c": "x"})
    by_trial = bootstrap_by(frame, "v", "c", unit="trial", seed=1)["x"]
    by_person = bootstrap_by(frame, "v", "c", unit="participant", seed=1)["x"]
    assert by_person.high - by_person.low > 1.5 * (by_trial.high - by_trial.low)
    empty = bootstrap_by(frame, "v", "c", levels=["x", "y"])["y"]
    assert empty.n == 0 and empty.text() == "no data"
    with pytest.raises(AnalysisError, match="no column 'w'"):
        bootstrap_by(frame, "w", "c")


def test_tables_reproduce_the_reference_descriptives():
    ref_dir = require(SHARED_DATA / "lme4_reference", "the lme4 reference numbers")
    ref = json.loads((ref_dir / "lme4_reference.json").read_text())["sim_descriptives"]
    trials = pd.read_csv(ref_dir / "sim_trials.csv").assign(complete=True, translation_distance=1.0)
    picks = pd.read_csv(ref_dir / "sim_picks.csv").rename(columns={"chosen_rank": "rank"})
    picks["reciprocal_rank"] = 1 / picks["rank"]
    conditions = ["manual", "suggest_noorient", "suggest"]
    t1 = {r["condition"]: r for r in table1(trials, picks, conditions, resamples=200).data}
    t2 = {r["condition"]: r for r in table2(picks, conditions).data}
    for c in conditions:
        assert t1[c]["trials"] == ref[c]["n_trials"]
        assert t1[c]["total_time_mean"] == pytest.approx(ref[c]["mean_total_time"], rel=1e-12)
        assert t1[c]["rotation_time_mean"] == pytest.approx(ref[c]["mean_rotation_time"], rel=1e-12)
        assert t1[c]["translation_time_mean"] == pytest.approx(ref[c]["mean_translation_time"], rel=1e-12)
        assert t1[c]["n_queries_mean"] == pytest.approx(ref[c]["mean_n_queries"], rel=1e-12)
        assert t1[c]["reciprocal_rank_mean"] == pytest.approx(ref[c]["mrr_pooled"], rel=1e-12)
        assert t1[c]["reciprocal_rank_n"] == ref[c]["n_picks"]
        assert t1[c]["total_time_low"] < t1[c]["total_time_mean"] < t1[c]["total_time_high"]
        assert t2[c]["picks"] == ref[c]["n_picks"]
        for b in ("1", "2", "3", "4+"):
            assert t2[c][f"rank_{b}"] == ref[c]["rank_counts"][b]
            assert t2[c][f"share_{b}"] == pytest.approx(ref[c]["rank_props"][b])


@pytest.mark.slow
def test_report_from_an_export_holds_every_table_and_figure(synthetic, tmp_path):
    out = tmp_path / "report"
    summary = build_report(read_export(synthetic), out, resamples=200, seed=4)
    for name in ("table1", "table2", "lr_tests", "random_effects", "contrasts", "survey"):
        for ext in ("md", "tex", "csv"):
            assert (out / "tables" / f"{name}.{ext}").stat().st_size > 0
    steps = pd.read_csv(out / "tables" / "random_effects.csv")
    for measure, test in summary["tests"].items():  # every measure's last step is the structure its test used
        last = steps[steps["measure"] == measure].iloc[-1]
        assert last["decision"].startswith("kept") and last["structure"] == test["selection"]["kept"], measure
    for name in ("time_by_scene", "rank_distribution", "learning_curves"):
        assert (out / "figures" / f"{name}.png").read_bytes()[:4] == b"\x89PNG"
        assert b"<svg" in (out / "figures" / f"{name}.svg").read_bytes()[:500]
    readme = (out / "README.md").read_text()
    assert "seed 4" in readme and "12 participants arrived, 11 completed" in readme
    assert "1 scheduled trial(s) were not completed" in readme and "![time_by_scene]" in readme
    assert "\\toprule" in (out / "tables" / "table1.tex").read_text()
    trials = pd.read_csv(out / "measures" / "trials.csv")
    done = trials[trials["complete"]]
    rows = {r["condition"]: r for r in summary["table1"]}
    assert rows["full"]["total_time_mean"] == pytest.approx(done.loc[done.condition == "full", "total_time"].mean())
    assert all("error" not in t for t in summary["tests"].values())
    assert summary["tests"]["total_time"]["lrt"]["df"] == 2
    again = build_report(read_export(synthetic), tmp_path / "again", resamples=200, seed=4)
    assert again["table1"] == summary["table1"]
    completers = build_report(read_export(synthetic), tmp_path / "completers", resamples=50, completed_only=True)
    assert completers["trials"]["scheduled"] == 11 * 9 == completers["trials"]["completed"]
    assert any("did not finish" in n for n in completers["notes"])


def test_bad_exports_get_messages_and_the_report_keeps_what_it_can(synthetic, tmp_path):
    broken = tmp_path / "broken"
    broken.mkdir()
    for f in synthetic.iterdir():
        (broken / f.name).write_bytes(f.read_bytes())
    trials = pd.read_csv(broken / "trials.csv")
    trials.drop(columns="condition").to_csv(broken / "trials.csv", index=False)
    with pytest.raises(AnalysisError, match=r"trials.csv: column 'condition' is missing"):
        read_export(broken)
    # an unknown condition, and a defined condition without any data
    trials.loc[trials["condition"] == "basic", "condition"] = "turbo"
    trials.to_csv(broken / "trials.csv", index=False)
    summary = build_report(read_export(broken), tmp_path / "report", resamples=50)
    notes = " ".join(summary["notes"])
    assert "condition the study does not define (turbo)" in notes and "'basic' has no completed trials" in notes
    rows = {r["condition"]: r for r in summary["table1"]}
    assert rows["basic"]["trials"] == 0 and rows["full"]["trials"] > 0
    assert summary["tests"]["total_time"]["lrt"]["df"] == 1  # none vs full only
    assert "no data" in (tmp_path / "report" / "tables" / "table1.md").read_text()
    with pytest.raises(AnalysisError, match="is missing from the export"):
        read_export(tmp_path)


def test_report_reads_the_database_directly_like_the_export(app, tmp_path):
    from study_server.experimenter.export import export_to

    assert Bot(FlaskTransport(app.test_client()), "demo", "bot-a", np.random.default_rng(1)).run().code
    url = app.config["SQLALCHEMY_DATABASE_URI"]
    with app.app_context():
        export_to(app.extensions["studies"]["demo"], tmp_path / "export")
    from_db, from_export = read_database(url), read_export(tmp_path / "export")
    assert from_db.conditions == from_export.conditions == ["none", "basic", "full"]
    a, b = trials_table(from_db), trials_table(from_export)
    assert a["complete"].all() and len(a) == 9
    pd.testing.assert_series_equal(a["total_time"], b["total_time"])
    assert a["score"].notna().all()  # stored at "done", exported as stored
    pd.testing.assert_series_equal(a["score"], b["score"])
    picked = picks_table(from_db, a)
    assert len(picked) > 0
    pd.testing.assert_frame_equal(picked, picks_table(from_export, b))
    answers = [d.survey.sort_values(["participant", "survey", "question"]).reset_index(drop=True)
               for d in (from_db, from_export)]
    assert len(answers[0]) > 0
    pd.testing.assert_frame_equal(*answers, check_dtype=False)
    with pytest.raises(AnalysisError, match="no study 'nope'"):
        read_database(url, "nope")


def _cli(*args, env=None):
    return subprocess.run([sys.executable, "-m", "scenesuggest.cli", "analyze", *args], capture_output=True,
                          text=True, env={**os.environ, **(env or {})})


def test_cli_lmm_and_bootstrap_print_the_documented_json(tmp_path):
    ref_dir = require(SHARED_DATA / "lme4_reference", "the lme4 reference numbers")
    proc = _cli("lmm", str(ref_dir / "sim_trials.csv"), "--response", "total_time", "--fixed", "condition",
                "--random", "participant", "--random", "scene", "--reference", "manual", "--json")
    assert proc.returncode == 0, proc.stderr
    out = json.loads(proc.stdout)
    assert set(out) >= {"nobs", "loglik", "fixed", "variance", "lrt"}
    assert set(out["variance"]) == {"participant", "scene", "residual"}
    assert set(out["lrt"]) == {"chi2", "df", "p", "null_loglik"} and out["lrt"]["df"] == 2
    assert out["fixed"]["(Intercept)"]["estimate"] == pytest.approx(416.40138333334, rel=1e-6)
    proc = _cli("bootstrap", str(ref_dir / "sim_trials.csv"), "--value", "total_time", "--by", "condition",
                "--unit", "participant", "--seed", "3", "--json")
    out = json.loads(proc.stdout)
    assert out["unit"] == "participant" and out["seed"] == 3 and out["resamples"] == 1000
    assert set(out["by"]["manual"]) == {"mean", "low", "high", "n"} and out["by"]["manual"]["n"] == 60


def test_cli_errors_name_the_problem(tmp_path):
    bad = tmp_path / "t.csv"
    bad.write_text("participant,condition,y\np1,a,1\np1,b,2\np2,a,3\np2,b,4\n")
    proc = _cli("lmm", str(bad), "--response", "time", "--fixed", "condition", "--random", "participant")
    assert proc.returncode == 2 and "no column 'time'" in proc.stderr and "Traceback" not in proc.stderr
    proc = _cli("lmm", str(bad), "--response", "y", "--fixed", "condition", "--random", "participant",
                "--reference", "z")
    assert proc.returncode == 2 and "reference level 'z'" in proc.stderr
    proc = _cli("report", "--export", str(tmp_path / "none"), "--out", str(tmp_path / "r"))
    assert proc.returncode == 2 and "is not a folder" in proc.stderr
    proc = _cli("lmm", str(tmp_path / "missing.csv"), "--response", "y", "--fixed", "c", "--random", "p")
    assert proc.returncode == 2 and "missing.csv" in proc.stderr


@pytest.mark.slow
def test_cli_report_shows_progress(synthetic, tmp_path):
    proc = _cli("report", "--export", str(synthetic), "--out", str(tmp_path / "r"), "--resamples", "100", "--json")
    assert proc.returncode == 0, proc.stderr
    assert "bootstrap intervals" in proc.stderr and "model of total_time" in proc.stderr
    assert json.loads(proc.stdout)["trials"]["completed"] == 12 * 9 - 1


@pytest.mark.slow
def test_power_resamples_pilot_participants(synthetic):
    from analysis.power import power
    from analysis.report import select

    trials, picks, _, conditions, _ = select(read_export(synthetic))
    a = power(trials, picks, conditions, [4, 10], studies=2, seed=2)
    assert a == power(trials, picks, conditions, [4, 10], studies=2, seed=2)
    assert set(a["power"]) == {"4", "10"} and a["pilot_participants"] == 12
    assert a["power"]["10"]["total_time"] == 1.0  # the synthetic effect is large
    assert all(0.0 <= v <= 1.0 for row in a["power"].values() for v in row.values())
    one = trials[trials["participant"] == trials["participant"].iloc[0]]
    with pytest.raises(AnalysisError, match="1 participant"):
        power(one, picks, conditions, [6], studies=1)


def test_a_pilot_without_picks_yet_gets_table_1_with_no_data_for_mrr(synthetic):
    """A measure nobody has data for yet (a first pilot placed nothing from a list) is 'no data' in the table;
    asked for directly, the same column is an error naming it."""
    from analysis.measures import picks_table

    trials = trials_table(read_export(synthetic))
    picks = picks_table(read_export(synthetic), trials).iloc[0:0]
    t1 = table1(trials, picks, ["none", "basic", "full"], resamples=50)
    assert all(row[-1] == "no data" for row in t1.rows) and all(r["reciprocal_rank_n"] == 0 for r in t1.data)
    assert all(row[2] != "no data" for row in t1.rows)  # the times are there
    with pytest.raises(AnalysisError, match="has no numeric values"):
        bootstrap_by(picks, "reciprocal_rank", "condition")
