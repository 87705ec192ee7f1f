"""Admin pages: login (rate-limited, CSRF), progress, timelines, exclusion, previews, export."""

import io
import re
import zipfile

import pytest
from demostudy import make_app
from flowhelp import EXIT, auth, csrf, finish_all_trials, to_trials
from werkzeug.security import generate_password_hash

from study_server.base.extensions import db
from study_server.base.models import Participant
from study_server.trials.replays import scene_after

PASSWORD = "correct horse battery staple"


@pytest.fixture
def admin_app(tmp_path, demo_resources):
    return make_app(tmp_path, ADMIN_PASSWORD_HASH=generate_password_hash(PASSWORD))


def login(c, password=PASSWORD):
    page = c.get("/admin/login")
    return c.post("/admin/login", data={"csrf_token": csrf(page), "password": password})


def test_admin_pages_need_a_login(admin_app):
    c = admin_app.test_client()
    for path in ("/admin/", "/admin/demo/participants", "/admin/demo/participants/1", "/admin/demo/preview",
                 "/admin/demo/export.zip", "/admin/demo/preview/full/bedside"):
        r = c.get(path)
        assert r.status_code == 302 and "/admin/login" in r.headers["Location"], path
    assert c.post("/admin/demo/participants/1/exclude", data={"reason": "x"}).status_code == 302


def test_login_is_checked_rate_limited_and_needs_csrf(admin_app):
    c = admin_app.test_client()
    assert c.post("/admin/login", data={"password": PASSWORD}).status_code == 400  # no CSRF token
    assert login(c, "wrong").status_code == 401
    for _ in range(4):
        login(c, "wrong")
    assert login(c).status_code == 429  # five failures: even the right password waits
    other = admin_app.test_client()
    other.environ_base["REMOTE_ADDR"] = "10.0.0.9"  # another address is not blocked
    r = login(other)
    assert r.status_code == 302 and other.get("/admin/").status_code == 200


def test_login_starts_a_fresh_session(admin_app):
    c = admin_app.test_client()
    c.get("/admin/login")
    with c.session_transaction() as s:
        s["planted"] = "by an attacker"
    login(c)
    with c.session_transaction() as s:
        assert "planted" not in s and isinstance(s["admin"], str) and len(s["admin"]) >= 32


def test_progress_timeline_exclusion_and_xss(admin_app):
    participant = admin_app.test_client()
    b = to_trials(participant)
    finish_all_trials(participant, b)
    page = participant.get("/study/demo/")
    participant.post("/study/demo/exit", data={"csrf_token": csrf(page), **EXIT, "last_seq": "29", "attempt": "0"})
    to_trials(admin_app.test_client(), query="pid=second")
    c = admin_app.test_client()
    login(c)
    dash = c.get("/admin/").data.decode()
    assert "Completed 1 of 12 planned" in dash and "in progress 1" in dash
    assert re.search(r"<td>0</td>\s*<td>none → basic → full</td>", dash)
    with admin_app.app_context():
        pid = db.session.query(Participant).filter_by(platform_id="p1").one().id
        second = db.session.query(Participant).filter_by(platform_id="second").one()
    timeline = c.get(f"/admin/demo/participants/{pid}").data
    assert b"trial_start" in timeline and b"<script>alert" not in timeline and b"&lt;script&gt;" in timeline
    r = c.post(f"/admin/demo/participants/{second.id}/exclude", data={"csrf_token": csrf(c.get("/admin/")),
                                                                      "reason": "bot-like"})
    assert r.status_code == 302
    with admin_app.app_context():
        p = db.session.get(Participant, second.id)
        assert p.status == "excluded" and p.excluded_reason == "bot-like"
        from study_server.base.models import utcnow
        from study_server.participants.assignment import row_counts

        assert row_counts(admin_app.extensions["studies"]["demo"].study, utcnow())[second.row] == 0
    assert c.post(f"/admin/demo/participants/{pid}/exclude", data={"reason": "x"}).status_code == 400  # CSRF
    assert c.post(f"/admin/demo/participants/{pid}/exclude",
                  data={"csrf_token": csrf(c.get("/admin/")), "reason": ""}).status_code == 400


def test_preview_and_export(admin_app):
    participant = admin_app.test_client()
    b = to_trials(participant)
    participant.post("/api/events", headers=auth(b), json={"page_id": "p", "events": [
        {"seq": 0, "t": 1.0, "type": "insert", "trial": -1, "payload": {
            "object": "o1", "model": "ai2thor:Plate", "category": "Plate", "rank": 2, "source": "context"}}]})
    c = admin_app.test_client()
    login(c)
    grid = c.get("/admin/demo/preview").data
    assert grid.count(b"/admin/demo/preview/") == 12  # 3 conditions × 4 scenes
    page = c.get("/admin/demo/preview/basic/bedside")
    assert page.status_code == 200 and b'"preview": true' in page.data
    r = c.get("/admin/demo/export.zip", buffered=False)
    assert r.status_code == 200 and r.mimetype == "application/zip"
    assert r.is_streamed and "Content-Length" not in r.headers  # sent as it is written
    z = zipfile.ZipFile(io.BytesIO(b"".join(r.response)))
    names = {n.split("/", 1)[1] for n in z.namelist()}
    assert {"participants.csv", "trials.csv", "events.csv", "suggestions.csv", "picks.csv", "survey.csv",
            "manifest.json", "data_dictionary.md", "event_schema.json"} <= names
    picks = z.read("demo/picks.csv").decode().splitlines()
    assert picks[0].startswith("participant,seq,trial") and ",2,0.5,context," in picks[1]


def test_search_text_and_worker_ids_are_escaped_on_admin_pages(admin_app):
    payload = "<img src=x onerror=alert(1)>"
    participant = admin_app.test_client()
    b = to_trials(participant, query="pid=" + payload.replace(" ", "%20").replace("=", "%3D"))
    event = {"seq": 0, "t": 1.0, "type": "search", "trial": b["trial"]["index"], "payload": {"text": payload}}
    assert participant.post("/api/events", json={"page_id": b["page_id"], "events": [event]},
                            headers=auth(b)).status_code == 200
    c = admin_app.test_client()
    login(c)
    with admin_app.app_context():
        pid = db.session.query(Participant).one().id
    for path in ("/admin/", "/admin/demo/participants", f"/admin/demo/participants/{pid}"):
        page = c.get(path).data
        assert b"<img src=x" not in page, path
    assert b"&lt;img src=x onerror=alert(1)&gt;" in c.get(f"/admin/demo/participants/{pid}").data


def test_every_admin_form_needs_its_csrf_token(admin_app):
    c = admin_app.test_client()
    login(c)
    posts = [r for r in admin_app.url_map.iter_rules() if r.endpoint.startswith("admin.") and "POST" in r.methods]
    assert {r.endpoint for r in posts} >= {"admin.login", "admin.logout", "admin.exclude"}
    for rule in posts:
        path = re.sub(r"<row[^>]*>", "0", rule.rule.replace("<study_id>", "demo").replace("<scene_id>", "bedside")
                      .replace("<secret>", "x"))
        r = c.post(path, data={"reason": "x", "password": PASSWORD})
        assert r.status_code == 400, (path, r.status_code)
    assert c.get("/admin/").status_code == 200  # still logged in: nothing was done without the token


def test_the_replay_of_a_trial_in_progress_and_of_one_without_states(monkeypatch, admin_app):
    """The replay's data: the trial so far, the scene after each event (from the server's replay), the models to
    draw; events of vocabulary 1 give the events without scenes and say why; admins only."""
    from statehelp import insert, obj

    participant = admin_app.test_client()
    b = to_trials(participant)
    rt = admin_app.extensions["studies"]["demo"]
    table = next(o for o in rt.scene(b["trial"]["scene"], "target")["objects"] if o["category"] == "DiningTable")
    events = [{**insert(0, table), "trial": -1}, {**insert(1, obj("plate", 0.1, parent=table["id"],
                                                                model=table["model_id"])), "trial": -1}]
    assert participant.post("/api/events", headers=auth(b), json={"page_id": "p", "vocabulary": 2,
                                                                  "events": events}).status_code == 200
    with admin_app.app_context():
        pid = db.session.query(Participant).one().id
    path = f"/admin/demo/participants/{pid}/trials/-1/replay.json"
    assert participant.get(path).status_code == 302  # not an admin
    c = admin_app.test_client()
    login(c)
    doc = c.get(path).json
    assert doc["trial"]["done"] is False and doc["problem"] is None and len(doc["events"]) == 2
    assert [len(scene_after(doc, e["scene"])) for e in doc["events"]] == [2, 3]  # the room, then one more each
    assert [len(s["set"]) for s in doc["steps"]] == [1, 1]  # each step carries what changed, not the scene again
    assert {m["id"] for m in doc["models"]} >= {table["model_id"]}
    assert c.get(f"/admin/demo/participants/{pid}/trials/-1/replay").status_code == 200
    assert c.get(f"/admin/demo/participants/{pid}/trials/7/replay.json").status_code == 200
    assert c.get(f"/admin/demo/participants/{pid}/trials/42/replay.json").status_code == 404
    from study_server.trials import replays

    with monkeypatch.context() as m:
        m.setattr(replays, "MAX_SHOWN_STATES", 2)  # the start's room, then 1 object: the second is too many
        doc = c.get(path).json
        assert doc["problem"].startswith("this trial changed its scene too often to show every step here")
        assert [e["scene"] for e in doc["events"]] == [1, 1] and len(doc["steps"]) == 1
    old = {"seq": 2, "t": 1.7e12, "type": "delete", "trial": -1, "payload": {"object": "plate"}}
    assert participant.post("/api/events", headers=auth(b), json={"page_id": "p", "events": [old]}).status_code == 200
    doc = c.get(path).json
    assert doc["problem"].startswith("this trial cannot be replayed from seq 2 on: a delete event without object")
    assert [e["scene"] for e in doc["events"]] == [1, 2, 2] and len(doc["steps"]) == 2  # the steps before it


def test_one_unreadable_row_does_not_take_down_the_admin_pages_or_the_export(admin_app):
    """A cell changed behind the app's back (a time that is no time, flags that are not JSON) reads as missing: the
    dashboard, the participants, each participant's page and the export still answer, the bad time shown as
    unreadable."""
    from sqlalchemy import text

    for i in range(3):
        to_trials(admin_app.test_client(), query=f"pid=p{i}")
    with admin_app.app_context():
        db.session.execute(text("UPDATE participants SET created_at = 'yesterday' WHERE id = 1"))
        db.session.execute(text("UPDATE participants SET flags = '[not json', last_seen_at = 'x' WHERE id = 2"))
        db.session.execute(text("UPDATE trials SET started_at = '2026-02-31 10:00:00' WHERE id = 1"))
        db.session.commit()
    c = admin_app.test_client()
    login(c)
    for path in ("/admin/", "/admin/demo/participants", "/admin/demo/participants/1", "/admin/demo/participants/2",
                 "/admin/demo/participants/3"):
        assert c.get(path).status_code == 200, path
    listing = c.get("/admin/demo/participants").get_data(as_text=True)
    assert "unreadable" in listing and listing.count("/admin/demo/participants/") >= 3
    r = c.get("/admin/demo/export.zip")
    assert r.status_code == 200
    z = zipfile.ZipFile(io.BytesIO(r.data))
    assert len(z.read("demo/participants.csv").decode().splitlines()) == 4


def test_a_participants_page_stays_small_whatever_they_stored(admin_app):
    """600 searches of 2,000 '&' each (escaped, 6 MB on one page before): the page shows 250 events at a time, each
    payload cut after 600 characters and said to be cut, with links to the earlier and later events."""
    from integrityhelp import event, post_events

    participant = admin_app.test_client()
    b = to_trials(participant)
    for first in range(0, 600, 200):
        r = post_events(participant, b, [event(i, text="&" * 2000) for i in range(first, first + 200)])
        assert r.status_code == 200, r.json
    c = admin_app.test_client()
    login(c)
    pages, url = [], "/admin/demo/participants/1"
    while url:
        page = c.get(url).get_data(as_text=True)
        pages.append(page)
        later = re.search(r'href="([^"]+)">later events', page)
        url = later.group(1).replace("&amp;", "&") if later else None
    assert len(pages) == 3 and all(len(p) < 2_000_000 for p in pages), [len(p) for p in pages]
    assert pages[0].count("characters more: the export holds them") == 250
    assert "event 0<" in pages[0] and "event 250<" in pages[1] and "event 599<" in pages[2]
    assert "earlier events" in pages[1] and "earlier events" not in pages[0]


@pytest.mark.parametrize("value", ["1" + "0" * 30, "2147483648", "-5", "abc", "\u0661", ""])
def test_a_participants_page_names_a_from_that_is_no_event_seq(admin_app, value):
    to_trials(admin_app.test_client())
    c = admin_app.test_client()
    login(c)
    r = c.get("/admin/demo/participants/1", query_string={"from": value})
    assert r.status_code == 400 and b"from" in r.data and b"Traceback" not in r.data
