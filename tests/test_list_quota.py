"""What a participant can make the server store is bounded: lists shown (searches, context suggestions) against a
rate and the participant's storage quota, with 429 and Retry-After beyond them, and never at a person's pace;
reloads and refused requests count on one session-log row instead of adding rows."""

from __future__ import annotations

from datetime import timedelta

import pytest
from flowhelp import auth, to_trials

from study_server.base.extensions import db
from study_server.base.models import Participant, SessionLog, ShownList, utcnow
from study_server.trials import lists


class Clock:
    """The lists' clock, moved by hand: minutes of requests in a moment."""

    def __init__(self):
        self.now = utcnow()

    def __call__(self):
        return self.now


@pytest.fixture
def clock(monkeypatch):
    c = Clock()
    monkeypatch.setattr(lists, "utcnow", c)
    return c


def test_a_person_searching_twice_a_second_for_ten_minutes_is_never_refused(client, app, clock):
    b = to_trials(client)
    codes = []
    for i in range(1200):  # 2 a second, 10 minutes
        codes.append(client.get(f"/api/search?q=chair{i % 7}", headers=auth(b)).status_code)
        clock.now += timedelta(seconds=0.5)
    assert codes == [200] * 1200
    with app.app_context():
        assert db.session.query(ShownList).count() == 1200


def test_a_script_is_held_to_the_list_rate_with_retry_after_then_let_through(client, app, clock):
    b = to_trials(client)
    codes = [client.get("/api/search?q=chair", headers=auth(b)).status_code for _ in range(lists.LIST_RATE)]
    assert codes == [200] * lists.LIST_RATE  # all at once: the window's whole allowance
    for _ in range(3):
        refused = client.get("/api/search?q=chair", headers=auth(b))
        assert refused.status_code == 429 and refused.json["field"] == "search"
    wait = int(refused.headers["Retry-After"])
    assert 1 <= wait <= lists.LIST_WINDOW.total_seconds() + 1
    r = client.post("/api/suggest", headers=auth(b), json={"trial": b["trial"]["index"]})
    assert r.status_code in (403, 429)  # the practice may have no suggestions; never stored either way
    clock.now += timedelta(seconds=wait)
    assert client.get("/api/search?q=chair", headers=auth(b)).status_code == 200
    with app.app_context():
        assert db.session.query(ShownList).count() == lists.LIST_RATE + 1
        rows = [r for r in db.session.query(SessionLog).filter_by(kind="quota") if r.detail["what"] == "search lists"]
        assert len(rows) == 1 and rows[0].detail["times"] == 3  # the refusals counted on one row


def test_lists_count_against_the_participants_storage_quota(client, app, clock):
    b = to_trials(client)
    with app.app_context():
        p = db.session.query(Participant).one()
        quota = int(app.extensions["studies"]["demo"].study.max_mb_per_participant * 1024 * 1024)
        p.bytes_stored = quota - 10
        db.session.commit()
    r = client.get("/api/search?q=chair", headers=auth(b))
    assert r.status_code == 429 and "as much as a study allows" in r.json["error"] and r.headers["Retry-After"]
    with app.app_context():
        assert db.session.query(ShownList).count() == 0
        p = db.session.query(Participant).one()
        p.bytes_stored = 0
        db.session.commit()
    assert client.get("/api/search?q=chair", headers=auth(b)).status_code == 200
    with app.app_context():
        stored = db.session.query(Participant).one().bytes_stored
        assert stored > 0  # the list counted


def test_reloads_and_refused_posts_do_not_grow_the_session_log(client, app):
    to_trials(client)
    with app.app_context():
        before = db.session.query(SessionLog).count()
    for _ in range(50):
        assert client.get("/study/demo/").status_code == 200
        assert client.get("/study/demo/start?pid=p1").status_code == 302
    with app.app_context():
        rows = db.session.query(SessionLog).count()
        times = sum(r.detail.get("times", 1) for r in db.session.query(SessionLog).filter_by(kind="resume"))
    assert rows - before <= 4 and times >= 99  # the first view of the trial page is a view, then resumes
