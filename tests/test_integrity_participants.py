"""Nobody can take over or fake a participant, and a completion code means the work was done: each attack as it
was found (HTTP against the server, on SQLite and on PostgreSQL where storage is involved), and what the
participant sees instead."""

from __future__ import annotations

import io
import zipfile

import pytest
from demostudy import make_app
from flowhelp import EXIT, auth, csrf, enter, finish_all_trials, next_trial, to_trials
from integrityhelp import PASSWORD, PID, SESSION, STUDY, event, participant_of, post_events, study_copy
from werkzeug.security import generate_password_hash

from simulation.walker import CAPABLE_DEVICE
from study_server.base.extensions import db
from study_server.base.models import Participant, Trial, utcnow
from study_server.participants.assignment import row_counts


# --- takeover -----------------------------------------------------------------------------------------------------
def test_a_prolific_id_alone_does_not_resume_a_participant_elsewhere(tmp_path, demo_resources):
    app = make_app(tmp_path, studies=[study_copy(tmp_path, platform="prolific")])
    victim = app.test_client()
    link = f"PROLIFIC_PID={PID}&STUDY_ID={STUDY}&SESSION_ID={SESSION}"
    b = to_trials(victim, query=link)
    for query in (f"PROLIFIC_PID={PID}", f"PROLIFIC_PID={PID}&STUDY_ID={STUDY}",
                  f"PROLIFIC_PID={PID}&STUDY_ID={STUDY}&SESSION_ID={'9' * 24}"):
        attacker = app.test_client()
        r = attacker.get(f"/study/demo/start?{query}")
        assert r.status_code in (409, 422) and b"Traceback" not in r.data, query
        page = attacker.get("/study/demo/")
        assert b'id="boot"' not in page.data and b["token"].encode() not in page.data
        assert b"Please start this study" in page.data
    p = participant_of(app, PID)
    assert any("another browser" in f["reason"] for f in p.flags)  # the experimenter sees the attempt
    # the participant's own link in a new browser (Prolific's SESSION_ID) resumes the session
    again = app.test_client()
    assert again.get(f"/study/demo/start?{link}").status_code == 302
    assert b["token"].encode() in again.get("/study/demo/").data
    with app.app_context():
        assert db.session.query(Participant).count() == 1


def test_a_plain_links_pid_does_not_resume_from_another_browser(client, app):
    b = to_trials(client, query="pid=victim")
    other = app.test_client()
    r = other.get("/study/demo/start?pid=victim")
    assert r.status_code == 409 and b"already in progress in another browser" in r.data
    assert b["token"].encode() not in other.get("/study/demo/").data


def test_a_refused_attempt_on_an_id_says_who_raised_it_and_the_experimenter_can_clear_it(tmp_path, demo_resources):
    """Someone else opening a participant's link is refused (409); the owner's flag says from which (keyed)
    address and how often, the decision turns to review, and once the experimenter has looked and cleared it,
    the participant is approved again (the flag stays on record, cleared)."""
    from study_server.participants.outcomes import decision

    app = make_app(tmp_path, ADMIN_PASSWORD_HASH=generate_password_hash(PASSWORD))
    owner = app.test_client()
    owner.environ_base["REMOTE_ADDR"] = "198.51.100.1"
    b = to_trials(owner, query="pid=guessable-7")
    finish_all_trials(owner, b)
    page = owner.get("/study/demo/")
    owner.post("/study/demo/exit", data={"csrf_token": csrf(page), **EXIT})
    for _ in range(3):
        other = app.test_client()
        other.environ_base["REMOTE_ADDR"] = "203.0.113.50"
        assert other.get("/study/demo/start?pid=guessable-7").status_code == 409
    p = participant_of(app, "guessable-7")
    [f] = p.flags
    assert f["times"] == 3 and f["by"] and f["by"] != p.address and decision(p) == "review"
    admin = app.test_client()
    page = admin.get("/admin/login")
    admin.post("/admin/login", data={"csrf_token": csrf(page), "password": PASSWORD})
    shown = admin.get(f"/admin/demo/participants/{p.id}").get_data(as_text=True)
    assert f["by"][:12] in shown and "not the address this participant arrived from" in shown and "3 times" in shown
    assert admin.post(f"/admin/demo/participants/{p.id}/flags/0/clear", data={}).status_code in (400, 403)
    assert admin.post(f"/admin/demo/participants/{p.id}/flags/5/clear",
                      data={"csrf_token": csrf(admin.get("/admin/"))}).status_code == 404
    r = admin.post(f"/admin/demo/participants/{p.id}/flags/0/clear", data={"csrf_token": csrf(admin.get("/admin/"))})
    assert r.status_code == 302
    p = participant_of(app, "guessable-7")
    assert p.flags[0]["cleared_at"] and decision(p) == "approve"
    approvals = admin.get("/admin/demo/approvals.csv").get_data(as_text=True)
    assert ",approve,0," in approvals
    assert "cleared" in admin.get(f"/admin/demo/participants/{p.id}").get_data(as_text=True)
    anonymous = app.test_client()
    assert anonymous.post(f"/admin/demo/participants/{p.id}/flags/0/clear").status_code == 302  # to the login


def test_a_nul_in_the_entry_links_id_is_refused_calmly(app_on):
    r = app_on.test_client().get("/study/demo/start?pid=a%00b")
    assert r.status_code == 422 and b"pid" in r.data and b"Traceback" not in r.data
    with app_on.app_context():
        assert db.session.query(Participant).count() == 0


# --- completion codes that mean something -------------------------------------------------------------------------
def test_a_completion_without_work_is_completed_but_flagged_with_the_reason(app_on):
    c = app_on.test_client()
    b = to_trials(c)
    trial = b["trial"]
    for _ in range(10):  # "done" for every trial, no event at all (past each condition's instructions)
        r = c.post("/api/trial/done", headers=auth(b), json={"trial": trial["index"]})
        assert r.status_code == 200
        if r.json["step"] == "exit":
            break
        trial = next_trial(c)["trial"]
    assert r.json["step"] == "exit"
    page = c.get("/study/demo/")
    done = c.post("/study/demo/exit", data={"csrf_token": csrf(page), **EXIT}, follow_redirects=True)
    assert b"DEMO-DONE-7F3A" in done.data  # the code is given …
    p = participant_of(app_on, "p1")
    assert p.status == "completed" and len(p.flags) == 1  # … and the experimenter is told why to look
    assert "0 object(s) placed < 1" in p.flags[0]["reason"] and "no events" in p.flags[0]["reason"]
    with app_on.app_context():
        reviews = [t.review for t in db.session.query(Trial).filter_by(kind="trial")]
        assert len(reviews) == 9 and all(r and "no events" in r for r in reviews)
    admin = app_on.test_client()
    page = admin.get("/admin/login")
    admin.post("/admin/login", data={"csrf_token": csrf(page), "password": PASSWORD})
    assert b"completed without the minimum work" in admin.get(f"/admin/demo/participants/{p.id}").data
    assert b"review" in admin.get("/admin/demo/participants").data
    z = zipfile.ZipFile(io.BytesIO(admin.get("/admin/demo/export.zip").data))
    assert "completed without the minimum work" in z.read("demo/participants.csv").decode()
    assert "0 object(s) placed" in z.read("demo/trials.csv").decode()


def test_a_participant_who_did_the_work_is_not_flagged(client, app):
    b = to_trials(client)
    finish_all_trials(client, b)  # one insert per trial, 12 s of events
    page = client.get("/study/demo/")
    client.post("/study/demo/exit", data={"csrf_token": csrf(page), **EXIT})
    p = participant_of(app, "p1")
    assert p.status == "completed" and p.flags == []


@pytest.mark.parametrize(("query", "message"), [
    ("PROLIFIC_PID=made-up&STUDY_ID=" + STUDY, b"PROLIFIC_PID is not a valid prolific id"),
    (f"PROLIFIC_PID={PID}&STUDY_ID={'a' * 24}", b"STUDY_ID is not this study"),
    (f"PROLIFIC_PID={PID}", b"STUDY_ID is missing"),
])
def test_made_up_or_foreign_prolific_ids_are_refused(tmp_path, demo_resources, query, message):
    app = make_app(tmp_path, studies=[study_copy(tmp_path, platform="prolific")])
    r = app.test_client().get(f"/study/demo/start?{query}")
    assert r.status_code == 422 and message in r.data
    with app.app_context():
        assert db.session.query(Participant).count() == 0


@pytest.mark.parametrize("pid", ["p1\u202e", "p\u200b1", "\ufeffp1", "p1\u2028", "p1\u2029", "p\u0085", "p\ue000",
                                 "p\u2066x\u2069", "x" * 129, "p\u31641", "p\ufe0f1", "p\u034f1", "e\u0301"])
def test_a_plain_links_id_with_invisible_characters_is_refused(client, pid):
    """Bidi overrides, zero-width and line separators would let one id read as another on the admin pages and in
    the export."""
    from urllib.parse import quote

    r = client.get(f"/study/demo/start?pid={quote(pid)}")
    assert r.status_code == 422 and b"pid is not a valid link id" in r.data
    assert client.get("/study/demo/start?pid=" + quote("Ünïcode p1 ok")).status_code == 302


def test_coming_back_under_another_id_after_declining_is_flagged(tmp_path, demo_resources):
    app = make_app(tmp_path, studies=[study_copy(tmp_path, platform="prolific")])
    c = app.test_client()
    page = enter(c, query=f"PROLIFIC_PID={PID}&STUDY_ID={STUDY}")
    token = csrf(page)
    c.post("/study/demo/device", data={**CAPABLE_DEVICE, "csrf_token": token})
    c.post("/study/demo/consent", data={"csrf_token": token, "agree": "no"})
    other = "9" * 24
    assert c.get(f"/study/demo/start?PROLIFIC_PID={other}&STUDY_ID={STUDY}").status_code == 302
    second = participant_of(app, other)
    assert any("already took part" in f["reason"] and "no_consent" in f["reason"] for f in second.flags)
    assert participant_of(app, PID).flags  # both ids point at each other


def test_an_exclusion_is_final_and_nothing_is_taken_after_the_end(app_on):
    c = app_on.test_client()
    b = to_trials(c)
    assert post_events(c, b, [event(0)]).status_code == 200
    p = participant_of(app_on, "p1")
    admin = app_on.test_client()
    page = admin.get("/admin/login")
    admin.post("/admin/login", data={"csrf_token": csrf(page), "password": PASSWORD})
    page = admin.get(f"/admin/demo/participants/{p.id}")
    admin.post(f"/admin/demo/participants/{p.id}/exclude", data={"csrf_token": csrf(page), "reason": "bot"})
    r = post_events(c, b, [event(1)])
    assert r.status_code == 410 and r.json["status"] == "excluded"
    assert c.post("/api/trial/done", headers=auth(b), json={"trial": b["trial"]["index"]}).status_code == 410
    assert c.post("/api/suggest", headers=auth(b), json={"trial": b["trial"]["index"]}).status_code == 410
    seen = participant_of(app_on, "p1").last_seen_at
    assert c.post("/api/heartbeat", headers=auth(b)).status_code == 410  # an ended session is not seen any more
    assert participant_of(app_on, "p1").last_seen_at == seen
    page = c.get("/study/demo/")
    assert b"This session has ended" in page.data and b'id="boot"' not in page.data
    with app_on.app_context():  # finishing the survey later changes nothing
        q = db.session.get(Participant, p.id)
        q.step = "exit"
        db.session.commit()
    c.post("/study/demo/exit", data={"csrf_token": c.form_token, **EXIT})
    q = participant_of(app_on, "p1")
    assert q.status == "excluded" and q.code is None
    with app_on.app_context():
        assert row_counts(app_on.extensions["studies"]["demo"].study, utcnow())[q.row] == 0  # the row is free


def test_events_after_completion_are_refused(client, app):
    b = to_trials(client)
    finish_all_trials(client, b)
    page = client.get("/study/demo/")
    client.post("/study/demo/exit", data={"csrf_token": csrf(page), **EXIT})
    r = post_events(client, b, [event(999)])
    assert r.status_code == 410 and r.json["status"] == "completed"


def test_a_form_token_that_is_not_ascii_is_an_expired_form_not_a_crash(client):
    enter(client)
    r = client.post("/study/demo/consent", data={"csrf_token": "é", "agree": "yes"})
    assert r.status_code == 400 and b"expired" in r.data


def test_a_study_without_its_prolific_id_configured_takes_links_without_study_id(tmp_path, demo_resources):
    path = study_copy(tmp_path, platform="prolific")
    path.write_text(path.read_text().replace(f'study_id = "{STUDY}"', ""))
    app = make_app(tmp_path, studies=[path])
    assert app.test_client().get(f"/study/demo/start?PROLIFIC_PID={PID}").status_code == 302


def test_an_exclusion_committed_while_the_exit_survey_is_submitted_wins(app_on):
    from study_server.participants import flow

    c = app_on.test_client()
    to_trials(c)
    with app_on.app_context():
        study = app_on.extensions["studies"]["demo"].study
        p = db.session.query(Participant).one()  # loaded as in progress …
        with db.engine.begin() as other:  # … while the experimenter's exclusion commits
            other.execute(Participant.__table__.update().values(status="excluded"))
        with pytest.raises(flow.SessionEnded):
            flow.submit_exit(p, study, {})
        db.session.rollback()
        assert db.session.query(Participant).one().status == "excluded"
