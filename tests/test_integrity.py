"""Nobody can take over, poison or fake a participant: each attack as it was found (HTTP against the server, on
SQLite and on PostgreSQL where storage is involved), and what the participant sees instead."""

from __future__ import annotations

import io
import json
import os
import stat
import zipfile
from datetime import timedelta

import pytest
from conftest import DEMO_STUDY, make_app
from flowhelp import EXIT, auth, csrf, enter, finish_all_trials, to_trials
from werkzeug.security import generate_password_hash

from scenesuggest.cells import safe_cell, unescape_cell
from study_server.assignment import row_counts
from study_server.extensions import db
from study_server.models import AdminSession, Event, Participant, SessionLog, Trial, utcnow

PASSWORD = "correct horse battery staple"
PID, STUDY, SESSION = "5f3a" + "0" * 20, "6a1b" + "1" * 20, "7c2d" + "2" * 20


def study_copy(tmp_path, name="study", platform=None, **limits):
    """The demo study file with another platform and other limits (its scenes and resources still the demo's)."""
    text = DEMO_STUDY.read_text().replace('"../../var/', f'"{DEMO_STUDY.parents[2]}/var/')
    text = text.replace('target = "scenes/', f'target = "{DEMO_STUDY.parent}/scenes/')
    if platform:
        text = text.replace('kind = "link"', f'kind = "{platform}"\nstudy_id = "{STUDY}"')
    for key, value in limits.items():
        text = text.replace("[limits]\n", f"[limits]\n{key} = {value}\n") if f"\n{key} =" not in text else \
            __import__("re").sub(rf"\n{key} = [^\n]*", f"\n{key} = {value}", text)
    path = tmp_path / f"{name}.toml"
    path.write_text(text)
    return path


@pytest.fixture(params=["sqlite", "postgresql"])
def backend_url(request, tmp_path, demo_resources):
    if request.param == "postgresql":
        return request.getfixturevalue("postgres_db")
    return f"sqlite:///{tmp_path / 'study.sqlite3'}"


@pytest.fixture
def app_on(backend_url, tmp_path):
    return make_app(tmp_path, backend_url, ADMIN_PASSWORD_HASH=generate_password_hash(PASSWORD))


def participant_of(app, platform_id) -> Participant:
    with app.app_context():
        p = db.session.query(Participant).filter_by(platform_id=platform_id).one()
        db.session.expunge(p)
        return p


def post_events(c, b, events, page_id=None):
    return c.post("/api/events", headers=auth(b), json={"page_id": page_id or b["page_id"], "events": events})


def event(seq, type_="search", trial=0, t=None, **payload):
    return {"seq": seq, "t": t if t is not None else 1.0e12 + seq, "type": type_, "trial": trial,
            "payload": payload or {"text": f"query {seq}"}}


# --- takeover and silent loss ------------------------------------------------------------------------------------
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


def test_a_seq_held_by_other_content_is_a_conflict_never_a_silent_drop(app_on):
    c = app_on.test_client()
    b = to_trials(c)
    assert post_events(c, b, [event(0), event(1), event(2)]).json["acked_seq"] == 2
    r = post_events(c, b, [event(3), event(1, text="what the participant really searched")])
    assert r.status_code == 409 and r.json["conflicts"] == [1] and r.json["field"] == "events[1].seq"
    assert r.json["next_seq"] == 4
    with app_on.app_context():
        assert db.session.query(Event).count() == 3  # nothing of the refused batch
        assert db.session.query(SessionLog).filter_by(kind="event_conflict").one().detail["seqs"] == [1]
    # the same events again (a reload replaying its outbox under a new page id) are simply acknowledged
    assert post_events(c, b, [event(1), event(2)], page_id="another-page").json == {"acked_seq": 2, "stored": True}
    # the client sends its event under the seq the server handed out: stored, and nothing lost
    assert post_events(c, b, [event(3), event(4, text="what the participant really searched", t=1.0e12 + 1)]
                       ).json["acked_seq"] == 4


# --- one bad string -----------------------------------------------------------------------------------------------
@pytest.mark.parametrize(("events", "page_id", "field"), [
    ([event(0, text="\udfff")], None, "events[0].payload.text"),
    ([event(0, "list_shown", source="search", items=["ok", "\ud800x"])], None, "events[0].payload.items[1]"),
    ([event(0, text="nul\x00")], None, "events[0].payload.text"),
    ([event(0)], "page\udfff", "page_id"),
    ([event(0)], "page\x00", "page_id"),
    ([event(2**31)], None, "events[0].seq"),
])
def test_strings_that_cannot_be_stored_and_seqs_that_overflow_get_a_422(app_on, events, page_id, field):
    c = app_on.test_client()
    b = to_trials(c)
    body = json.dumps({"page_id": page_id or b["page_id"], "events": events})  # json escapes the surrogates
    r = c.post("/api/events", data=body, headers={**auth(b), "Content-Type": "application/json"})
    assert r.status_code == 422 and r.json["field"] == field, r.json
    with app_on.app_context():
        assert db.session.query(Event).count() == 0
    emoji = json.dumps({"page_id": b["page_id"], "events": [event(0, text="sofa \U0001F6CB")]})  # a surrogate pair
    assert c.post("/api/events", data=emoji, headers={**auth(b), "Content-Type": "application/json"}).status_code == 200


def test_a_nul_in_the_entry_links_id_is_refused_calmly(app_on):
    r = app_on.test_client().get("/study/demo/start?pid=a%00b")
    assert r.status_code == 422 and b"pid" in r.data and b"Traceback" not in r.data
    with app_on.app_context():
        assert db.session.query(Participant).count() == 0


def test_the_export_never_crashes_on_what_is_stored(app_on, tmp_path):
    c = app_on.test_client()
    b = to_trials(c)
    assert post_events(c, b, [event(0, "insert", object="o1", model="m", category="Sofa", rank=1,
                                    source="context")]).status_code == 200
    with app_on.app_context():  # text stored before the server refused it
        e = db.session.query(Event).one()
        e.payload = {**e.payload, "model": "bad\udfff"}  # JSON keeps it as an escape: the driver accepts it
        db.session.commit()
    admin = app_on.test_client()
    page = admin.get("/admin/login")
    admin.post("/admin/login", data={"csrf_token": csrf(page), "password": PASSWORD})
    r = admin.get("/admin/demo/export.zip")
    assert r.status_code == 200
    picks = zipfile.ZipFile(io.BytesIO(r.data)).read("demo/picks.csv").decode("utf-8")
    assert "bad\\udfff" in picks


# --- completion codes that mean something -------------------------------------------------------------------------
def test_a_completion_without_work_is_completed_but_flagged_with_the_reason(app_on):
    c = app_on.test_client()
    b = to_trials(c)
    trial = b["trial"]
    for _ in range(10):  # "done" for every trial, no event at all
        r = c.post("/api/trial/done", headers=auth(b), json={"trial": trial["index"]})
        assert r.status_code == 200
        trial = r.json["trial"]
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


def test_coming_back_under_another_id_after_declining_is_flagged(tmp_path, demo_resources):
    app = make_app(tmp_path, studies=[study_copy(tmp_path, platform="prolific")])
    c = app.test_client()
    page = enter(c, query=f"PROLIFIC_PID={PID}&STUDY_ID={STUDY}")
    token = csrf(page)
    c.post("/study/demo/device", data={"csrf_token": token, "width": "1400", "height": "900"})
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


# --- everything else ----------------------------------------------------------------------------------------------
def test_export_cells_cannot_run_as_formulas_and_load_back_unchanged(client, app, tmp_path):
    from analysis.load import read_export
    from study_server.export import export_to

    hostile = ["=HYPERLINK(\"http://evil\",\"x\")", "+cmd|' /C calc'!A0", "-2+3", "@SUM(A1)", "\tx", "\rx",
               "'quoted", "-12.5"]
    b = to_trials(client)
    assert post_events(client, b, [event(i, text=t) for i, t in enumerate(hostile)]).status_code == 200
    with app.app_context():
        export_to(app.extensions["studies"]["demo"].study, tmp_path / "export")
    raw = (tmp_path / "export" / "session_log.csv").read_text()
    assert all(not line.startswith(("=", "+", "@")) for line in raw.splitlines())
    assert [safe_cell(t) for t in hostile[:-1]] == ["'" + t for t in hostile[:-1]] and safe_cell("-12.5") == "-12.5"
    assert [unescape_cell(safe_cell(t)) for t in hostile] == hostile
    data = read_export(tmp_path / "export")
    searched = [p["text"] for p in data.events["payload"]]
    assert searched == hostile


def test_logout_ends_the_session_on_the_server_and_sessions_expire(app_on):
    admin = app_on.test_client()
    page = admin.get("/admin/login")
    admin.post("/admin/login", data={"csrf_token": csrf(page), "password": PASSWORD})
    copied = app_on.test_client()
    copied.set_cookie("session", admin.get_cookie("session").value)
    assert copied.get("/admin/demo/export.zip").status_code == 200
    page = admin.get("/admin/")
    admin.post("/admin/logout", data={"csrf_token": csrf(page)})
    r = copied.get("/admin/demo/export.zip")
    assert r.status_code == 302 and "/admin/login" in r.headers["Location"]
    page = admin.get("/admin/login")
    admin.post("/admin/login", data={"csrf_token": csrf(page), "password": PASSWORD})
    assert admin.get("/admin/").status_code == 200
    with app_on.app_context():  # idle for more than an hour
        for s in db.session.query(AdminSession):
            s.last_seen_at = utcnow() - timedelta(hours=2)
        db.session.commit()
    assert admin.get("/admin/").status_code == 302


def test_failed_logins_from_an_address_do_not_lock_out_an_admins_browser(app_on):
    admin = app_on.test_client()  # the admin has logged in from this browser before
    page = admin.get("/admin/login")
    assert admin.post("/admin/login", data={"csrf_token": csrf(page), "password": PASSWORD}).status_code == 302
    page = admin.get("/admin/")
    admin.post("/admin/logout", data={"csrf_token": csrf(page)})
    attacker = app_on.test_client()  # same address (127.0.0.1: behind a proxy, everyone's)
    page = attacker.get("/admin/login")
    codes = [attacker.post("/admin/login", data={"csrf_token": csrf(page), "password": "guess"}).status_code
             for _ in range(8)]
    assert codes == [401] * 5 + [429] * 3
    page = attacker.get("/admin/login")
    assert attacker.post("/admin/login", data={"csrf_token": csrf(page), "password": PASSWORD}).status_code == 429
    page = admin.get("/admin/login")
    assert admin.post("/admin/login", data={"csrf_token": csrf(page), "password": PASSWORD}).status_code == 302


def test_parallel_guesses_get_no_extra_tries(tmp_path, demo_resources):
    import re
    from concurrent.futures import ThreadPoolExecutor

    import requests
    from serverproc import StudyServer

    database = f"sqlite:///{tmp_path / 'study.sqlite3'}"
    make_app(tmp_path, database)
    os.environ["SCENESUGGEST_ADMIN_PASSWORD_HASH"] = generate_password_hash(PASSWORD)
    try:
        with StudyServer(tmp_path / "instance", database, workers=3, migrate=False) as server:
            def guess(i):
                s = requests.Session()
                token = re.search(r'name="csrf_token" value="([^"]+)"', s.get(f"{server.base}/admin/login").text)
                return s.post(f"{server.base}/admin/login", data={"csrf_token": token.group(1),
                                                                  "password": f"guess{i}"}, timeout=30).status_code
            with ThreadPoolExecutor(max_workers=12) as pool:
                codes = list(pool.map(guess, range(24)))
    finally:
        del os.environ["SCENESUGGEST_ADMIN_PASSWORD_HASH"]
    assert codes.count(401) == 5 and codes.count(429) == 19, codes


def test_visitors_who_do_not_consent_hold_no_row_and_do_not_freeze_authoring(app_on):
    for i in range(20):
        enter(app_on.test_client(), query=f"pid=visitor{i}")
    with app_on.app_context():
        assert row_counts(app_on.extensions["studies"]["demo"].study, utcnow()) == [0] * 6
        assert db.session.query(Trial).count() == 0
    admin = app_on.test_client()
    page = admin.get("/admin/login")
    admin.post("/admin/login", data={"csrf_token": csrf(page), "password": PASSWORD})
    page = admin.get("/admin/demo/author/bedside")
    assert b'"frozen": 0' in page.data or b"&#34;frozen&#34;: 0" in page.data


def test_arrivals_events_and_bytes_have_quotas(tmp_path, demo_resources):
    path = study_copy(tmp_path, arrivals_per_address_per_hour=3, max_events_per_participant=100,
                      max_mb_per_participant=0.2)
    app = make_app(tmp_path, studies=[path])
    for i in range(3):
        assert app.test_client().get(f"/study/demo/start?pid=a{i}").status_code == 302
    r = app.test_client().get("/study/demo/start?pid=a3")
    assert r.status_code == 429 and b"Too many people" in r.data
    far = app.test_client()
    far.environ_base["REMOTE_ADDR"] = "10.1.2.3"  # another address is not held back
    b = to_trials(far, query="pid=elsewhere")
    assert post_events(far, b, [event(i) for i in range(100)]).status_code == 200
    r = post_events(far, b, [event(100)])
    assert r.status_code == 429 and r.headers["Retry-After"] and r.json["field"] == "events"
    big = make_app(tmp_path / "big", studies=[path])
    c = big.test_client()
    b = to_trials(c, query="pid=bytes")
    payload = "x" * 1900
    codes = [post_events(c, b, [event(j * 50 + i, text=payload) for i in range(50)]).status_code for j in range(3)]
    assert codes == [200, 200, 429]  # 0.2 MB: two batches of 50 × 2 kB, not a third


def test_mturk_submit_hosts_and_login_next_and_asset_paths(tmp_path, demo_resources, client):
    app = make_app(tmp_path / "m", studies=[study_copy(tmp_path, platform="mturk")])
    ids = "workerId=A1B2C3D4E5F6G7&assignmentId=3AMW0RGHOD1P000000000000000000&hitId=3HYA4D452RIC111111111111111111"
    r = app.test_client().get(f"/study/demo/start?{ids}&turkSubmitTo=https://evil.example")
    assert r.status_code == 422 and b"turkSubmitTo" in r.data
    assert app.test_client().get(f"/study/demo/start?{ids}&turkSubmitTo=https://workersandbox.mturk.com"
                                 ).status_code == 302
    admin_app = make_app(tmp_path / "a", ADMIN_PASSWORD_HASH=generate_password_hash(PASSWORD))
    admin = admin_app.test_client()
    page = admin.get("/admin/login")
    r = admin.post("/admin/login?next=/admin/%0d%0aSet-Cookie:x=1", data={"csrf_token": csrf(page),
                                                                           "password": PASSWORD})
    assert r.status_code == 302 and r.headers["Location"] == "/admin/" and "Set-Cookie: x" not in str(r.headers)
    assert client.get("/study/demo/assets/models/../library.json").status_code == 404
    assert client.get("/study/demo/assets/thumbnails/../../library/library.json").status_code == 404


def test_database_files_and_admin_secrets_are_private(tmp_path, demo_resources):
    from study_server.config import ensure_admin_password

    os.umask(0o022)
    app = make_app(tmp_path)
    client = app.test_client()
    to_trials(client)
    files = [tmp_path / "study.sqlite3", tmp_path / "study.sqlite3-wal"]
    ensure_admin_password(tmp_path / "fresh")
    files += [tmp_path / "fresh" / "admin.json", tmp_path / "fresh" / "admin-password.txt"]
    for f in files:
        assert f.exists(), f
        assert stat.S_IMODE(f.stat().st_mode) == 0o600, (f, oct(f.stat().st_mode))
    assert stat.S_IMODE((tmp_path / "instance").stat().st_mode) == 0o700


# --- after review: the same attacks by other routes -----------------------------------------------------------------
def test_surrogates_sent_as_raw_bytes_and_deep_bodies_are_refused_not_stored(app_on):
    c = app_on.test_client()
    b = to_trials(c)
    head = {**auth(b), "Content-Type": "application/json"}
    raw = b'{"trial": -1, "scene": {"objects": [{"id": "x\xed\xa0\x80y"}]}}'  # a surrogate as (invalid) UTF-8
    r = c.post("/api/trial/done", data=raw, headers=head)
    assert r.status_code == 422 and r.json["field"] == "scene.objects[0].id"
    r = c.post("/api/suggest", data=b'{"trial": -1, "parent": "\xed\xbf\xbf"}', headers=head)
    assert r.status_code == 422 and r.json["field"] == "parent"
    deep = b'{"trial": -1, "scene": ' + b"[" * 980 + b'"\\udfff"' + b"]" * 980 + b"}"
    r = c.post("/api/trial/done", data=deep, headers=head)
    assert r.status_code in (400, 422) and "Traceback" not in r.get_data(as_text=True)
    assert c.get("/api/search?q=a%00b", headers=auth(b)).status_code == 400
    with app_on.app_context():
        assert db.session.query(Trial).filter(Trial.done_at.is_not(None)).count() == 0


def test_a_form_token_that_is_not_ascii_is_an_expired_form_not_a_crash(client):
    enter(client)
    r = client.post("/study/demo/consent", data={"csrf_token": "é", "agree": "yes"})
    assert r.status_code == 400 and b"expired" in r.data


def test_an_event_another_tab_already_stored_under_a_new_seq_is_acknowledged(app_on):
    c = app_on.test_client()
    b = to_trials(c)
    mine = event(0, text="mine")
    assert post_events(c, b, [event(0, text="theirs"), dict(mine, seq=1)]).json["acked_seq"] == 1
    r = post_events(c, b, [mine])  # this page still holds it under its first seq
    assert r.status_code == 200 and r.json["acked_seq"] == 1
    with app_on.app_context():
        assert db.session.query(Event).count() == 2


def test_a_study_without_its_prolific_id_configured_takes_links_without_study_id(tmp_path, demo_resources):
    path = study_copy(tmp_path, platform="prolific")
    path.write_text(path.read_text().replace(f'study_id = "{STUDY}"', ""))
    app = make_app(tmp_path, studies=[path])
    assert app.test_client().get(f"/study/demo/start?PROLIFIC_PID={PID}").status_code == 302


def test_login_limits_count_an_ipv6_block_as_one_client_and_cap_all_anonymous_clients(app_on, monkeypatch):
    from study_server import security

    def guess(address, password="guess"):
        c = app_on.test_client()
        c.environ_base["REMOTE_ADDR"] = address
        page = c.get("/admin/login")
        return c.post("/admin/login", data={"csrf_token": csrf(page), "password": password}).status_code
    codes = [guess(f"2001:db8:0:1::{i}") for i in range(1, 8)]  # one /64: one client
    assert codes == [401] * 5 + [429] * 2
    assert guess("2001:db8:0:2::1", PASSWORD) == 302  # the next /64 is another client
    monkeypatch.setattr(security, "ANONYMOUS_LOGIN_LIMIT", 8)
    codes = [guess(f"10.0.0.{i}") for i in range(1, 6)]  # every address new: the shared cap stops them
    assert codes.count(429) >= 2 and guess("10.0.1.1", PASSWORD) == 429


def test_an_exclusion_committed_while_the_exit_survey_is_submitted_wins(app_on):
    from study_server import flow

    c = app_on.test_client()
    to_trials(c)
    with app_on.app_context():
        study = app_on.extensions["studies"]["demo"].study
        p = db.session.query(Participant).one()  # loaded as in progress …
        with db.engine.begin() as other:  # … while the experimenter's exclusion commits
            other.execute(Participant.__table__.update().values(status="excluded"))
        with pytest.raises(ValueError):
            flow.submit_exit(p, study, {})
        db.session.rollback()
        assert db.session.query(Participant).one().status == "excluded"


def test_a_forged_or_foreign_device_cookie_buys_no_extra_guesses(app_on):
    from study_server.security import DEVICE_COOKIE

    def guesses(cookie):
        c = app_on.test_client()
        if cookie:
            c.set_cookie(DEVICE_COOKIE, cookie, path="/admin")
        page = c.get("/admin/login")
        return [c.post("/admin/login", data={"csrf_token": csrf(page), "password": "guess"}).status_code
                for _ in range(3)]
    assert guesses(None) + guesses(None) == [401] * 5 + [429]  # one address: five tries
    assert guesses("made-up.value.sig") == [429] * 3  # an unsigned cookie counts as the address
    assert guesses("x" * 3000) == [429] * 3  # a long one too (no 500)
