"""Pilots apart from the live study: simulated participants go into a database of their own by default; test runs
and bots let into a study's own database are pilots (signed entry links, marked in the database, the export and the
report) that take no part in the rows' balance, the targets' freeze or the approvals; `study reset` starts a study
clean before launch and refuses once real participants have arrived, unless forced."""

from __future__ import annotations

import json
import os
import sqlite3
import subprocess
import sys
from urllib.parse import urlencode

import pandas as pd
import pytest
from demostudy import DEMO_STUDY, make_app
from flowhelp import DEMOGRAPHICS, csrf
from integrityhelp import PASSWORD, study_copy
from support import ROOT
from werkzeug.security import generate_password_hash

from analysis.load import read_database, read_export
from analysis.report import PILOTS_ONLY, build_report
from simulation.run import simulate
from simulation.transport import FlaskTransport, FlowError
from simulation.walker import Walker
from study_server.base.extensions import db
from study_server.base.models import Event, Participant, SessionLog, Trial
from study_server.participants import outcomes, pilots
from study_server.participants.assignment import row_counts
from study_server.trials import posted_scenes

UA = {"User-Agent": "Mozilla/5.0 (X11; Linux x86_64) Chrome/150"}


def _consent(app, query: dict | str):
    """A participant through consent (a schedule row taken); their test client."""
    client = app.test_client()
    Walker(FlaskTransport(client), "demo").walk(lambda _: DEMOGRAPHICS, until=("briefing",),
                                                page=Walker(FlaskTransport(client), "demo").enter(query, UA))
    return client


def _people(app) -> dict[str, Participant]:
    with app.app_context():
        found = {p.platform_id: p for p in db.session.query(Participant)}
        for p in found.values():
            db.session.expunge(p)
        return found


def test_only_the_servers_key_makes_a_pilot(app):
    study = app.extensions["studies"]["demo"].study
    query = pilots.entry_query(app.config["SECRET_KEY"], study)
    client = _consent(app, query)
    real = _consent(app, {"pid": "real-1"})
    people = _people(app)
    assert people[query["pid"]].pilot and not people["real-1"].pilot
    for forged in ({"pid": "me", "pilot": query["pilot"]},  # another id's signature
                   {"pid": "me", "pilot": pilots.signature("not-the-key", "demo", "me")},
                   {"pid": "me", "pilot": ""}):
        r = app.test_client().get(f"/study/demo/start?{urlencode(forged)}", headers=UA)
        assert r.status_code == 422 and b"pilot is not a test link of this study" in r.data
    for raw in ("pid=me&pilot=%00", "pid=me&pilot=%ED%A0%80", "pid=me&pilot=" + "a" * 10_000_000,
                "pid=me&pilot=2147483648", "pilot=" + query["pilot"], "pid=me&pilot=x&pilot=" + query["pilot"]):
        r = app.test_client().get(f"/study/demo/start?{raw}", headers=UA)  # NUL, bad UTF-8, 10 MB, no id …
        assert r.status_code == 422 and b"pilot is not a test link of this study" in r.data, raw[:40]
    assert "me" not in _people(app)  # refused: no session made
    assert client and real


def test_pilots_take_no_part_in_the_balance_the_freeze_or_the_approvals(app):
    rt = app.extensions["studies"]["demo"]
    key = app.config["SECRET_KEY"]
    for _ in range(3):
        _consent(app, pilots.entry_query(key, rt.study))
    with app.app_context():
        now = pd.Timestamp.now("UTC").tz_localize(None)
        assert row_counts(rt.study, now) == [0] * rt.study.n_rows
        assert row_counts(rt.study, now, pilot=True) == [1, 1, 1] + [0] * (rt.study.n_rows - 3)  # balanced apart
        posted_scenes.may_author(rt)  # three pilots consented: the targets can still change
        rows = [r["decision"] for r in outcomes.approval_rows("demo")]
        assert rows == ["pilot"] * 3
    _consent(app, {"pid": "real-1"})
    people = _people(app)
    assert people["real-1"].row == 0  # the least-filled row, pilots not counted
    with app.app_context(), pytest.raises(posted_scenes.TargetsFrozen, match="1 participant"):
        posted_scenes.may_author(rt)


def test_the_dashboard_counts_pilots_and_visitors_apart_and_gives_a_test_link(tmp_path, demo_resources):
    app = make_app(tmp_path, ADMIN_PASSWORD_HASH=generate_password_hash(PASSWORD))
    _consent(app, pilots.entry_query(app.config["SECRET_KEY"], app.extensions["studies"]["demo"].study))
    _consent(app, {"pid": "real-1"})
    app.test_client().get("/study/demo/start?pid=just-looking", headers=UA)  # arrived, never consented
    admin = app.test_client()
    page = admin.get("/admin/login")
    admin.post("/admin/login", data={"csrf_token": csrf(page), "password": PASSWORD})
    html = admin.get("/admin/").get_data(as_text=True)
    totals = html.split('id="totals-demo">')[1].split("</p>")[0]
    assert "Completed 0 of 12 planned" in totals and "in progress 1" in totals
    assert "visiting, not consented yet 1" in totals and "pilots 1" in totals
    assert "the server does not stop there" in html
    link = html.split('id="pilot-link-demo">')[0].rsplit('href="', 1)[1].split('"')[0].replace("&amp;", "&")
    opened = app.test_client().get(link.split("localhost", 1)[1], headers=UA)
    assert opened.status_code == 302
    assert sum(p.pilot for p in _people(app).values()) == 2
    assert ('id="participant-link-demo">http://localhost/study/demo/start</code>') in html
    pilot = pilots.entry_query(app.config["SECRET_KEY"], app.extensions["studies"]["demo"].study)
    client = _consent(app, pilot)
    page = client.get("/study/demo/")
    client.post("/study/demo/leave", data={"csrf_token": csrf(page)})  # a pilot gets a code for leaving …
    assert _people(app)[pilot["pid"]].code == "DEMO-RETURNED"
    with app.app_context():
        assert outcomes.issued_codes("demo") == []  # … which is not the platform's to count


def test_a_pilot_is_sent_nowhere_at_the_end(tmp_path, demo_resources):
    path = study_copy(tmp_path, platform="mturk")
    app = make_app(tmp_path / "app", studies=[path])
    study = app.extensions["studies"]["demo"].study
    summary = simulate(1, seed=2, study="demo", app=app, entry=lambda i: pilots.entry_query(
        app.config["SECRET_KEY"], study))
    assert summary["completed"] == 1
    (p,) = _people(app).values()
    assert p.pilot and p.platform_meta["turkSubmitTo"] == "https://workersandbox.mturk.com"
    client = app.test_client()
    with client.session_transaction() as s:
        s["participants"] = {"demo": p.token}
    html = client.get("/study/demo/").get_data(as_text=True)
    assert "A test run (pilot)" in html and "externalSubmit" not in html and "platform-link" not in html


@pytest.mark.parametrize("platform", ["prolific", "mturk", None])
def test_simulated_participants_enter_as_the_studys_platform_sends_them(tmp_path, demo_resources, platform):
    path = study_copy(tmp_path, platform=platform)
    app = make_app(tmp_path / "app", studies=[path])
    study = app.extensions["studies"]["demo"].study
    summary = simulate(2, seed=1, study="demo", app=app, entry=lambda i: pilots.entry_query(
        app.config["SECRET_KEY"], study))
    assert summary["completed"] == 2 and not summary["failures"]
    people = list(_people(app).values())
    assert all(p.pilot and p.platform == (platform or "link") and p.status == "completed" for p in people)
    # without a platform's ids, an error names the parameter refused
    with pytest.raises(FlowError, match="entry link → 422: .*(PROLIFIC_PID|workerId) is missing") if platform else \
            pytest.raises(FlowError, match="pilot is not a test link"):
        Walker(FlaskTransport(app.test_client()), "demo").enter({"pid": "plain", "pilot": "0" * 32})


def _walk_pilot_and_real(app):
    key = app.config["SECRET_KEY"]
    study = app.extensions["studies"]["demo"].study
    simulate(2, seed=4, study="demo", app=app, entry=lambda i: pilots.entry_query(key, study))
    simulate(2, seed=5, study="demo", app=app)  # real participants (unsigned links)


@pytest.mark.slow
def test_the_export_marks_pilots_and_the_report_leaves_them_out(app, tmp_path):
    from study_server.experimenter.export import export_to

    _walk_pilot_and_real(app)
    with app.app_context():
        export_to(app.extensions["studies"]["demo"], tmp_path / "export")
    people = pd.read_csv(tmp_path / "export" / "participants.csv")
    assert people["pilot"].tolist() == [True, True, False, False]
    package = json.loads((tmp_path / "export" / "datapackage.json").read_text())
    field = next(f for r in package["resources"] if r["name"] == "participants" for f in r["schema"]["fields"]
                 if f["name"] == "pilot")
    assert field["type"] == "boolean" and "pilot" in field["description"]
    data = read_export(tmp_path / "export")
    report = build_report(data, tmp_path / "report", resamples=20)
    assert report["participants"]["analysed"] == 2 and report["participants"]["pilot"] == 2
    assert any("2 pilot participant(s)" in n and "left out" in n for n in report["notes"])
    both = build_report(data, tmp_path / "both", resamples=20, include_pilots=True)
    assert both["participants"]["analysed"] == 4
    only = data.participants["pilot"]
    data.participants = data.participants[only]
    data.trials = data.trials[data.trials["participant"].isin(data.participants["participant"])]
    visitor = pd.DataFrame([{**data.participants.iloc[0].to_dict(), "participant": "visitor", "pilot": False,
                             "status": "in_progress"}])  # arrived, never consented: no row, no trials
    data.participants = pd.concat([data.participants, visitor], ignore_index=True)
    alone = build_report(data, tmp_path / "alone", resamples=20)
    assert alone["notes"][0] == PILOTS_ONLY and alone["participants"]["analysed"] == 2
    assert "**Pilot data only:**" in (tmp_path / "alone" / "README.md").read_text()
    assert read_database(app.config["SQLALCHEMY_DATABASE_URI"]).participants["pilot"].sum() == 2


def test_a_reset_without_force_removes_pilots_alone_whoever_arrives_meanwhile(app, monkeypatch):
    """The count that allows a reset and the deletion are two statements: a real participant arriving between them
    stays (without --force only pilots are ever deleted)."""
    _walk_pilot_and_real(app)
    with app.app_context():
        real = {p.id for p in db.session.query(Participant).filter_by(pilot=False)}
        logged = db.session.query(SessionLog).filter(SessionLog.participant_id.in_(real)).count()
        monkeypatch.setattr(pilots, "counts", lambda study_id: {"pilot": 2, "real": 0})  # counted before they came
        pilots.reset("demo")
        db.session.commit()
        assert {p.pilot for p in db.session.query(Participant)} == {False}
        assert db.session.query(Participant).count() == 2
        assert db.session.query(SessionLog).filter(SessionLog.participant_id.in_(real)).count() == logged > 0


def test_reset_removes_pilots_and_refuses_real_participants_unless_forced(app):
    _walk_pilot_and_real(app)
    with app.app_context():
        with pytest.raises(pilots.RealParticipants, match="2 real participant"):
            pilots.reset("demo")
        removed = pilots.reset("demo", pilots_only=True)
        db.session.commit()
        assert removed["participants"] == 2 and removed["events"] > 0
        assert pilots.counts("demo") == {"pilot": 0, "real": 2}
        left = {p.id for p in db.session.query(Participant)}
        assert {e.participant_id for e in db.session.query(Event)} == left  # nothing of the pilots stays
        assert {t.participant_id for t in db.session.query(Trial)} == left
        pilots.reset("demo", force=True)
        db.session.commit()
        assert db.session.query(Participant).count() == db.session.query(Event).count() == 0


def _cli(*args, env):
    return subprocess.run([sys.executable, "-m", "scenesuggest.cli", "study", *args], capture_output=True, text=True,
                          env=env, cwd=ROOT, timeout=600, stdin=subprocess.DEVNULL)  # no one answers a question


@pytest.mark.slow
def test_a_pilot_by_command_leaves_the_live_database_untouched(tmp_path, demo_resources):
    live = tmp_path / "live.sqlite3"
    env = {**os.environ, "DATABASE_URL": f"sqlite:///{live}", "SCENESUGGEST_INSTANCE": str(tmp_path / "instance"),
           "SCENESUGGEST_STUDIES": str(DEMO_STUDY)}
    make_app(tmp_path / "made", f"sqlite:///{live}")  # the live database, migrated, with nobody in it
    run = _cli("simulate", "--participants", "2", "--json", env=env)
    assert run.returncode == 0, run.stderr
    summary = json.loads(run.stdout)
    pilot_db = tmp_path / "instance" / "pilot.sqlite3"
    assert summary["completed"] == 2 and summary["database"] == f"sqlite:///{pilot_db}"
    with sqlite3.connect(live) as con:
        assert con.execute("SELECT COUNT(*) FROM participants").fetchone() == (0,)  # untouched
    with sqlite3.connect(pilot_db) as con:
        assert con.execute("SELECT COUNT(*), SUM(pilot) FROM participants").fetchone() == (2, 2)
    text = _cli("simulate", "--participants", "1", env=env)
    printed = next(line for line in text.stdout.splitlines() if line.startswith("export: ")).split(": ", 1)[1]
    assert printed == f"scenesuggest study export --study {DEMO_STUDY} --db sqlite:///{pilot_db} --out pilot-export/"
    bare = {k: v for k, v in env.items() if k != "SCENESUGGEST_STUDIES"}  # works without the simulation's setting
    exported = subprocess.run(["bash", "-c", printed.replace("scenesuggest", f"{sys.executable} -m scenesuggest.cli",
                                                             1)], capture_output=True, text=True, env=bare,
                              cwd=tmp_path)
    assert exported.returncode == 0, exported.stderr
    assert pd.read_csv(tmp_path / "pilot-export" / "participants.csv")["pilot"].all()

    into_live = _cli("simulate", "--participants", "1", "--live", env=env)  # asked for: in, as a pilot
    assert into_live.returncode == 0, into_live.stderr
    with sqlite3.connect(live) as con:
        assert con.execute("SELECT COUNT(*), SUM(pilot) FROM participants").fetchone() == (1, 1)
        con.execute("INSERT INTO participants (study_id, study_hash, platform, platform_id, platform_meta, token, "
                    "row, seed, status, step, instruction_page, position, acked_seq, user_agent, created_at, "
                    "last_seen_at, flags, events_stored, bytes_stored, pilot) VALUES ('demo', 'h', 'link', 'real', "
                    "'{}', 'tok', 0, 1, 'in_progress', 'trial', 0, 0, -1, '', '2026-12-04', '2026-12-04', '[]', 0, "
                    "0, 0)")
    unasked = _cli("reset", "--study", "demo", "--pilots-only", "--json", env=env)  # no --yes, no answer: kept
    assert unasked.returncode == 1 and "Aborted" in unasked.stderr
    refused = _cli("reset", "--study", "demo", "--yes", env=env)
    assert refused.returncode == 2 and "1 real participant(s) have arrived" in refused.stderr
    assert "Traceback" not in refused.stderr
    pilots_gone = _cli("reset", "--study", "demo", "--pilots-only", "--yes", "--json", env=env)
    assert pilots_gone.returncode == 0 and json.loads(pilots_gone.stdout)["removed"]["participants"] == 1
    forced = _cli("reset", "--study", str(DEMO_STUDY), "--force", "--yes", env=env)  # by its study file
    assert forced.returncode == 0 and "removed 1 participant(s) of demo" in forced.stdout
    with sqlite3.connect(live) as con:
        assert con.execute("SELECT COUNT(*) FROM participants").fetchone() == (0,)


def test_a_database_named_on_the_command_line_is_read_as_named_or_refused_saying_why(tmp_path, demo_resources,
                                                                                    monkeypatch):
    """A relative SQLite path is relative to where the command runs; a missing file is not made, an empty one or a
    URL that names no database is refused naming --db, never with a traceback."""
    from click.testing import CliRunner

    from scenesuggest.cli import main

    make_app(tmp_path / "made", f"sqlite:///{tmp_path / 'here.sqlite3'}")
    monkeypatch.chdir(tmp_path)
    monkeypatch.setenv("SCENESUGGEST_INSTANCE", str(tmp_path / "instance"))
    (tmp_path / "empty.sqlite3").touch()
    runner = CliRunner()
    for url, said in (("sqlite:///here.sqlite3", "exported demo to out"),
                      ("sqlite:///nowhere/x.sqlite3", f"no database file {tmp_path}/nowhere/x.sqlite3"),
                      ("sqlite:///empty.sqlite3", "holds no study data (no participants table)"),
                      ("nonsense://", "is not a database URL")):
        run = runner.invoke(main, ["study", "export", "--study", str(DEMO_STUDY), "--db", url, "--out", "out"])
        assert said in run.output and "Traceback" not in run.output, run.output
        assert run.exit_code == (0 if said.startswith("exported") else 2)
    assert not (tmp_path / "nowhere").exists()
    wrong = runner.invoke(main, ["study", "export", "--study", "my-study", "--out", "out2"])
    assert wrong.exit_code == 2 and "name its study file (--study path/to/study.toml), or set SCENESUGGEST_STUDIES" \
        in wrong.output
