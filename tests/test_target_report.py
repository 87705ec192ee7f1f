"""From the log to the report: picks defined once for the export and the analysis, "How close to the target" and
the score over time, and data written before events carried object states."""

import json

import pandas as pd
import pytest
from demostudy import make_app

from analysis.load import read_export
from analysis.report import build_report
from scenesuggest.contract.events import SCENE_CHANGES
from simulation.run import simulate
from study_server.base.extensions import db
from study_server.experimenter.export import export_to


@pytest.fixture(scope="module")
def bot_study(tmp_path_factory, demo_resources):
    """Three simulated participants on the demo, exported and analysed."""
    tmp = tmp_path_factory.mktemp("bots")
    app = make_app(tmp)
    assert simulate(3, seed=4, study="demo", app=app)["completed"] == 3
    with app.app_context():
        export_to(app.extensions["studies"]["demo"], tmp / "export")
    summary = build_report(read_export(tmp / "export"), tmp / "report", resamples=200)
    assert not (tmp / "export" / "event_schema_v1.json").exists()  # nothing of version 1 to describe
    return tmp, summary


def test_mrr_from_the_final_rows_of_picks_csv_is_the_reports(bot_study):
    tmp, summary = bot_study
    picks = pd.read_csv(tmp / "export" / "picks.csv")
    trials = pd.read_csv(tmp / "export" / "trials.csv")
    done = trials[(trials["kind"] == "trial") & trials["done_at"].notna()][["participant", "trial", "condition"]]
    assert set(picks["final"]) == {True, False}  # suggestions placed at once, then replaced in place
    chosen = picks[picks["final"] & picks["rank"].notna()].merge(done, on=["participant", "trial"])
    mrr = (1.0 / chosen["rank"]).groupby(chosen["condition"]).mean()
    reported = {row["condition"]: row["reciprocal_rank_mean"] for row in summary["table1"]}
    assert mrr.to_dict() == pytest.approx(reported, rel=1e-12)


def test_the_report_says_how_close_each_condition_came_to_the_targets(bot_study):
    tmp, summary = bot_study
    rows = {r["condition"]: r for r in summary["closeness"]}
    assert set(rows) == {"none", "basic", "full"}
    assert all(r["score_mean"] > 0.95 and r["missing_mean"] == 0 for r in rows.values())  # bots rebuild targets
    readme = (tmp / "report" / "README.md").read_text()
    assert "How close to the target" in readme and "closeness_over_time.png" in readme
    assert (tmp / "report" / "figures" / "closeness_over_time.png").stat().st_size > 10_000
    over_time = pd.read_csv(tmp / "report" / "measures" / "score_over_time.csv")
    first, last = over_time["elapsed_s"].min(), over_time["elapsed_s"].max()
    assert over_time.loc[over_time["elapsed_s"] == first, "score"].max() == 0.0  # nothing placed yet
    assert over_time.loc[over_time["elapsed_s"] == last, "score"].min() > 0.95
    scenes = json.loads((tmp / "export" / "scenes.json").read_text())
    assert set(scenes["scenes"]) >= {"practice", "desk-corner"} and scenes["taxonomy"] and scenes["symmetry_deg"]


def test_a_database_written_before_events_carried_states_still_exports_and_analyses(tmp_path, demo_resources):
    """Rolled back to the schema before this one, with the payloads pages of that time sent, then upgraded: the
    export has every table, final scores from the final scenes, and the report notes what cannot be rebuilt."""
    from flask_migrate import downgrade, upgrade
    from sqlalchemy import text

    from study_server import MIGRATIONS

    app = make_app(tmp_path)
    simulate(2, seed=2, study="demo", app=app)
    with app.app_context():
        downgrade(directory=str(MIGRATIONS), revision="8e0bab6dcada")
        for id_, payload in db.session.execute(text("SELECT id, payload FROM events WHERE type IN "
                                                    f"{tuple(SCENE_CHANGES)}")).all():
            old = {k: v for k, v in json.loads(payload).items() if k != "objects"}
            db.session.execute(text("UPDATE events SET payload = :p WHERE id = :i"), {"p": json.dumps(old), "i": id_})
        db.session.commit()
        upgrade(directory=str(MIGRATIONS))
        export_to(app.extensions["studies"]["demo"], tmp_path / "export")
    events = pd.read_csv(tmp_path / "export" / "events.csv")
    trials = pd.read_csv(tmp_path / "export" / "trials.csv")
    assert set(events["vocabulary"]) == {1} and trials["replay"].isna().all()
    assert trials["score"].notna().sum() == 20  # scored from the final scenes
    old_schema = json.loads((tmp_path / "export" / "event_schema_v1.json").read_text())
    assert old_schema["x-vocabulary-version"] == 1  # the version the data speaks is described
    summary = build_report(read_export(tmp_path / "export"), tmp_path / "report", resamples=100)
    assert summary["closeness"] and summary["trials"]["completed"] == 18
    assert any("without object states" in n for n in summary["notes"])
    assert not (tmp_path / "report" / "figures" / "closeness_over_time.png").exists()


def test_scores_that_differ_by_condition_get_the_same_test_as_the_times(bot_study, tmp_path):
    """Bots rebuild every target, so their scores cannot be modelled; scores set to differ by condition (none
    0.6, basic 0.75, full 0.9, with noise) through the export give the LR test and contrasts in that order."""
    import shutil

    import numpy as np

    tmp, _ = bot_study
    shutil.copytree(tmp / "export", tmp_path / "export")
    trials = pd.read_csv(tmp_path / "export" / "trials.csv")
    rng = np.random.default_rng(0)
    level = trials["condition"].map({"none": 0.6, "basic": 0.75, "full": 0.9})
    trials["score"] = np.where(trials["score"].notna(), level + rng.normal(0.0, 0.05, len(trials)), np.nan)
    trials.to_csv(tmp_path / "export" / "trials.csv", index=False)
    summary = build_report(read_export(tmp_path / "export"), tmp_path / "report", resamples=200)
    test = summary["tests"]["score"]
    assert not test.get("error") and test["lrt"]["df"] == 2 and test["lrt"]["p"] < 1e-3, test
    assert test["selection"]["intercepts_only"]["p"] < 1e-6  # (the structure kept may have slopes: more cautious)
    contrasts = {c["contrast"]: c["estimate"] for c in test["contrasts"]}
    assert contrasts["full − none"] == pytest.approx(0.3, abs=0.06)
    assert contrasts["basic − none"] == pytest.approx(0.15, abs=0.06)
    rows = {r["condition"]: r["score_mean"] for r in summary["closeness"]}
    assert rows["none"] < rows["basic"] < rows["full"]
