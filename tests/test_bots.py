"""Simulated participants: the whole flow through the HTTP interface, in process and against gunicorn, and the
analysis of what they did."""

from __future__ import annotations

import json
import os
import sqlite3
import subprocess
import sys

import numpy as np
import pandas as pd
import pytest
from demostudy import DEMO_STUDY, gunicorn, make_app
from support import ROOT

from analysis.load import read_database, read_export
from analysis.measures import picks_table, trials_table
from analysis.report import build_report
from simulation.actions import words
from simulation.participant import Bot
from simulation.run import simulate
from simulation.transport import FlaskTransport


def test_helpers():
    assert words("DeskLamp") == "desk lamp" and words("TV") == "tv"


def test_a_bot_completes_the_demo_and_everything_it_logged_is_stored(tmp_path, demo_resources):
    app = make_app(tmp_path)
    bot = Bot(FlaskTransport(app.test_client()), "demo", "bot-a", np.random.default_rng(1))
    result = bot.run()
    assert result.code and result.trials == 9 and result.missing_objects == 0
    assert set(result.condition_seconds) == {"none", "basic", "full"}
    data = read_database(app.config["SQLALCHEMY_DATABASE_URI"])
    assert len(data.events) == result.events and data.events["seq"].tolist() == list(range(result.events))
    trials = trials_table(data)
    assert trials["complete"].all() and len(trials) == 9
    # what the analysis measures is what the bot spent
    for condition, seconds in result.condition_seconds.items():
        measured = trials.loc[trials["condition"] == condition, "total_time"].tolist()
        assert sorted(measured) == pytest.approx(sorted(seconds), abs=1e-3)
    picks = picks_table(data, trials)
    context = picks[(picks["source"] == "context") & picks["final"]]
    # in basic/full the bot picks the target's model at the rank the engine gave its category
    assert len(context) > 0 and context["rank"].ge(1).all()
    shown = data.events[data.events["type"] == "list_shown"]
    assert (shown["payload"].map(lambda p: p["source"]) == "context").sum() >= len(context)
    survey = data.survey.set_index("question")["answer"]
    assert survey["preference"] in {"The model list", "Suggestions", "Suggestions, oriented"}


@pytest.mark.slow
def test_simulated_study_over_real_http_feeds_the_report(tmp_path, demo_resources):
    with gunicorn(tmp_path) as (base, database):
        summary = simulate(3, seed=5, url=base, study="demo")
    assert summary["completed"] == 3 and summary["trials"] == 27 and not summary["failures"]
    with sqlite3.connect(database) as con:
        stored = con.execute("SELECT COUNT(*), COUNT(DISTINCT participant_id || '-' || seq) FROM events").fetchone()
        rows = [r[0] for r in con.execute("SELECT row FROM participants ORDER BY id")]
    assert stored == (summary["events"], summary["events"])  # none lost, none twice
    assert len(set(rows)) == 3  # three different schedule rows
    data = read_database(f"sqlite:///{database}")
    report = build_report(data, tmp_path / "report", resamples=100)
    assert report["trials"]["completed"] == 27
    errors = {k: t["error"] for k, t in report["tests"].items() if t.get("error")}
    # bots leave drags and turns within a person's tolerance, inside the score's full credit: the score has nothing
    # to model; every other measure is tested
    assert errors == {"score": "is constant; there is no variance to model"}


def test_simulation_is_reproducible_from_its_seed(tmp_path, demo_resources):
    a = simulate(2, seed=3, study="demo", app=make_app(tmp_path / "a"))
    b = simulate(2, seed=3, study="demo", app=make_app(tmp_path / "b"))
    assert a == b and a["completed"] == 2


@pytest.mark.slow
def test_cli_simulate_then_export_then_report(tmp_path, demo_resources):
    env = {**os.environ, "DATABASE_URL": f"sqlite:///{tmp_path / 's.sqlite3'}",
           "SCENESUGGEST_INSTANCE": str(tmp_path / "instance"), "SCENESUGGEST_STUDIES": str(DEMO_STUDY)}
    cli = [sys.executable, "-m", "scenesuggest.cli"]
    proc = subprocess.run([*cli, "study", "simulate", "--participants", "2", "--live", "--json"],
                          capture_output=True, text=True, env=env, cwd=ROOT)
    assert proc.returncode == 0, proc.stderr
    assert json.loads(proc.stdout)["completed"] == 2 and "participant 2/2" in proc.stderr
    subprocess.run([*cli, "study", "export", "--study", "demo", "--out", str(tmp_path / "export")], check=True,
                   capture_output=True, env=env, cwd=ROOT)
    trials = trials_table(read_export(tmp_path / "export"))
    assert len(trials) == 18 and trials["complete"].all()
    bad = subprocess.run([*cli, "study", "simulate", "--url", "http://127.0.0.1:9"], capture_output=True,
                         text=True, env=env, cwd=ROOT)
    assert bad.returncode == 2 and "--study" in bad.stderr


def test_replaced_picks_are_not_final():
    from analysis.load import StudyData

    events = pd.DataFrame([
        {"participant": "1", "seq": 0, "type": "insert", "trial": 0, "client_t_ms": 0.0,
         "payload": {"object": "a", "rank": 1, "source": "context"}},
        {"participant": "1", "seq": 1, "type": "replace", "trial": 0, "client_t_ms": 1.0,
         "payload": {"object": "b", "replaces": "a", "rank": 3, "source": "context"}},
        {"participant": "1", "seq": 2, "type": "insert", "trial": 0, "client_t_ms": 2.0,
         "payload": {"object": "c", "rank": 2, "source": "search"}}])
    trials = pd.DataFrame([{"participant": "1", "trial": 0, "condition": "full", "scene": "s", "complete": True}])
    data = StudyData(pd.DataFrame(), trials, events, pd.DataFrame())
    picks = picks_table(data, trials)
    assert picks["final"].tolist() == [False, True, True]
    assert picks.loc[picks["final"], "rank"].tolist() == [3, 2]


@pytest.mark.slow
def test_mixed_behaviours_lose_nothing_and_duplicate_nothing(tmp_path, demo_resources):
    from simulation.participant import Behaviours

    app = make_app(tmp_path)
    behaviours = Behaviours(reload=0.3, second_tab=0.2, duplicate_arrival=0.5, resend=0.3, drop_out=0.25,
                            lossy=0.1, latency_s=0.002)
    summary = simulate(8, seed=11, study="demo", app=app, behaviours=behaviours)
    assert not summary["failures"] and summary["reloads"] > 0 and summary["dropped_out"] > 0
    assert summary["requests_repeated"] > 20  # lost requests and lost answers, all sent again
    assert summary["completed"] + summary["dropped_out"] == 8
    data = read_database(app.config["SQLALCHEMY_DATABASE_URI"])
    assert len(data.participants) == 8  # following the entry link again resumes, never enrols twice
    assert len(data.events) == summary["events"]
    assert not data.events.duplicated(["participant", "seq"]).any()
    for _, rows in data.events.groupby("participant"):
        assert rows["seq"].tolist() == list(range(len(rows)))  # no gap anywhere
    assert (data.events["type"] == "resume").sum() == summary["reloads"]
    assert (data.participants["status"] == "completed").sum() == summary["completed"]


@pytest.mark.slow
def test_every_trial_of_a_20_bot_study_with_mixed_behaviours_replays_to_its_final_scene(tmp_path, demo_resources):
    """Reloads, second tabs, repeated arrivals, resent batches, lossy requests and drop-outs (``--mix``): the
    server's replay of every finished trial gives the scene the bot submitted."""
    from simulation.participant import Behaviours
    from study_server.base.extensions import db
    from study_server.base.models import Trial

    app = make_app(tmp_path)
    summary = simulate(20, seed=0, study="demo", app=app, behaviours=Behaviours.mixed())
    assert not summary["failures"] and summary["reloads"] > 0
    with app.app_context():
        done = db.session.query(Trial).filter(Trial.done_at.isnot(None)).all()
        assert len(done) >= 150 and {t.replay for t in done} == {"match"}
        assert min(t.score for t in done) > 0.9
