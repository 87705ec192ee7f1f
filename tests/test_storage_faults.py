"""A database that cannot store data (full, read-only): the API answers 503 with Retry-After and stores
nothing, pages stay calm, and once the database recovers the same events arrive exactly once."""

from __future__ import annotations

from demostudy import make_app
from flowhelp import auth, to_trials
from sqlalchemy import event, text

from study_server.base.extensions import db


def _events(b, first, n):
    return [{"seq": first + i, "t": 1.0 + i, "type": "search", "trial": b["trial"]["index"],
             "payload": {"text": "x" * 1500}} for i in range(n)]


def test_a_full_database_answers_503_and_the_resent_events_arrive_once(tmp_path, demo_resources):
    app = make_app(tmp_path, f"sqlite:///{tmp_path / 'full.sqlite3'}")
    c = app.test_client()
    b = to_trials(c)
    send = lambda events: c.post("/api/events", json={"page_id": b["page_id"], "events": events},  # noqa: E731
                                 headers=auth(b))
    assert send(_events(b, 0, 5)).status_code == 200
    with app.app_context():
        pages = db.session.execute(text("PRAGMA page_count")).scalar()

        def cap(connection, record):  # SQLite's own size limit stands in for a full disk
            connection.execute(f"PRAGMA max_page_count = {pages}")
        event.listen(db.engine, "connect", cap)
        db.engine.dispose()
    batch = _events(b, 5, 200)
    r = send(batch)
    assert r.status_code == 503 and r.headers["Retry-After"] == "5"
    assert "cannot store data" in r.json["error"] and "Traceback" not in r.get_data(as_text=True)
    with app.app_context():
        event.remove(db.engine, "connect", cap)
        db.engine.dispose()
        assert db.session.execute(text("SELECT COUNT(*) FROM events")).scalar() == 5  # nothing half-written
    r = send(batch)  # the outbox sends the same batch again
    assert r.status_code == 200 and r.json["acked_seq"] == 204
    with app.app_context():
        assert db.session.execute(text("SELECT COUNT(*), COUNT(DISTINCT seq) FROM events")).one() == (205, 205)


def test_a_read_only_database_answers_503_and_pages_stay_calm(tmp_path, demo_resources):
    path = tmp_path / "ro.sqlite3"
    writer = make_app(tmp_path, f"sqlite:///{path}")
    c = writer.test_client()
    b = to_trials(c)
    reader = make_app(tmp_path, f"sqlite:///file:{path}?mode=ro&uri=true", CHECK_RESOURCES=False)
    r = reader.test_client().post("/api/events", json={"page_id": b["page_id"], "events": _events(b, 0, 3)},
                                  headers=auth(b))
    assert r.status_code == 503 and "cannot store data" in r.json["error"]
    r = reader.test_client().get("/study/demo/start?pid=newcomer", follow_redirects=True)
    assert r.status_code == 503 and b"Your work is kept" in r.data and b"Traceback" not in r.data
    r = c.post("/api/events", json={"page_id": b["page_id"], "events": _events(b, 0, 3)}, headers=auth(b))
    assert r.status_code == 200 and r.json["acked_seq"] == 2
