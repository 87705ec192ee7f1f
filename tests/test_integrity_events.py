"""Nobody can poison a participant's record: the events a page sends are stored once or refused with the field
to blame (a seq another sender holds, a string that cannot be stored, a quota spent), and the export of whatever
is stored neither crashes nor runs as a formula. HTTP against the server, on SQLite and on PostgreSQL."""

from __future__ import annotations

import io
import json
import zipfile

import pytest
from demostudy import make_app
from flowhelp import auth, csrf, to_trials
from integrityhelp import PASSWORD, event, post_events, study_copy

from scenesuggest.contract.cells import safe_cell, unescape_cell
from study_server.base.extensions import db
from study_server.base.models import Event, Participant, SessionLog, Trial


def test_a_batch_racing_a_later_one_is_acknowledged_up_to_everything_stored(app_on):
    """The usual batch (the next seqs, all new) is acknowledged without counting the stored seqs, unless the
    participant's event count says more are stored: then they are counted. A batch of later seqs that commits
    between reading the participant and storing (a race no sequential test can make) leaves neither the answer
    nor the participant's acked seq short of what is stored."""
    from study_server.participants import flow
    from study_server.trials import ingest

    c = app_on.test_client()
    b = to_trials(c)
    post = lambda seqs: post_events(c, b, [event(s) for s in seqs]).json["acked_seq"]  # noqa: E731
    assert post(range(3)) == 2  # the usual batch
    with app_on.app_context():
        stale = db.session.query(Participant).one()  # as read: acked 2, 3 stored
        db.session.expunge(stale)
    assert post(range(6, 9)) == 2  # the later batch wins the race: a gap
    with app_on.app_context():
        db.session.add(stale)  # the racing batch, with the participant as it read it (before the later one)
        assert ingest.store(stale, b["page_id"], [event(s) for s in range(3, 6)]) == 8
        p = db.session.query(Participant).one()
        assert (p.acked_seq, p.events_stored) == (8, 9) and flow.may_complete(p, 8, attempt=0)
        assert sorted(e.seq for e in db.session.query(Event)) == list(range(9))
    assert post(range(12, 14)) == 8  # a gap again: not acknowledged beyond it
    assert post(range(9, 12)) == 13  # the next seqs, and those beyond
    assert post(range(3, 6)) == 13  # a resend: stored once


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


def test_a_whole_librarys_list_is_stored_and_a_longer_one_refused_naming_it(app_on):
    """A fixed list of every model of a large library (the Stanford database's 1,580; ids of 40 characters) is one
    event the server stores whole; a list over MAX_STRINGS is refused with its field."""
    from scenesuggest.contract.events import MAX_STRINGS

    c = app_on.test_client()
    b = to_trials(c)
    library = [f"{i:040x}" for i in range(1580)]
    assert post_events(c, b, [event(0, "list_shown", source="fixed", items=library)]).status_code == 200
    with app_on.app_context():
        assert db.session.query(Event).one().payload["items"] == library
    r = post_events(c, b, [event(1, "list_shown", source="fixed", items=["m"] * (MAX_STRINGS + 1))])
    assert r.status_code == 422 and r.json["field"] == "events[0].payload.items", r.json
    assert f"at most {MAX_STRINGS} strings" in r.json["error"]


@pytest.mark.parametrize("key", ["id", "model_id", "category", "parent", "surface_type"])
def test_strings_in_object_states_are_bounded_as_they_arrive(app_on, key):
    """Every object state is kept and the admin's replay carries each: a long string in one (here 201
    characters) is refused naming it, so no trial's replay grows by what a page chose to send."""
    from statehelp import insert, obj

    from scenesuggest.contract.events import MAX_STATE_TEXT

    c = app_on.test_client()
    b = to_trials(c)

    def send(seq, state):
        return c.post("/api/events", headers=auth(b), json={"page_id": b["page_id"], "vocabulary": 2, "events": [
            {**insert(seq, state), "trial": b["trial"]["index"]}]})
    assert send(0, {**obj("a", 1.0), key: "x" * MAX_STATE_TEXT}).status_code == 200
    r = send(1, {**obj("b", 1.0), key: "x" * (MAX_STATE_TEXT + 1)})
    assert r.status_code == 422 and r.json["field"] == f"events[0].payload.objects[0].{key}", r.json
    assert f"at most {MAX_STATE_TEXT} characters" in r.json["error"]


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


def test_export_cells_cannot_run_as_formulas_and_load_back_unchanged(client, app, tmp_path):
    from analysis.load import read_export
    from study_server.experimenter.export import export_to

    hostile = ["=HYPERLINK(\"http://evil\",\"x\")", "+cmd|' /C calc'!A0", "-2+3", "@SUM(A1)", "\tx", "\rx",
               "'quoted", "\uff1dSUM(A1)", " =1+1", "\u00a0=1+1", "\ufeff=1+1", "|cmd", "\u200b=1", "\u202e=1",
               "'", "''x", "-12.5"]
    b = to_trials(client)
    assert post_events(client, b, [event(i, text=t) for i, t in enumerate(hostile)]).status_code == 200
    with app.app_context():
        export_to(app.extensions["studies"]["demo"], tmp_path / "export")
    raw = (tmp_path / "export" / "session_log.csv").read_text()
    assert all(not line.startswith(("=", "+", "@")) for line in raw.splitlines())
    assert [safe_cell(t) for t in hostile[:-1]] == ["'" + t for t in hostile[:-1]] and safe_cell("-12.5") == "-12.5"
    plain = ["text", "Ünïcode", "desk", '{"a": 1}', "[1, 2]", "2026-12-05 10:00", "", "_id", "１２"]
    assert [safe_cell(t) for t in plain] == plain  # JSON, dates and words stay as they are
    assert [unescape_cell(safe_cell(t)) for t in hostile + plain] == hostile + plain
    data = read_export(tmp_path / "export")
    searched = [p["text"] for p in data.events["payload"]]
    assert searched == hostile


def test_arrivals_events_and_bytes_have_quotas(tmp_path, backend_url):
    path = study_copy(tmp_path, arrivals_per_address_per_hour=3, max_events_per_participant=100,
                      max_mb_per_participant=0.2)
    app = make_app(tmp_path, backend_url, studies=[path])
    for i in range(3):
        assert app.test_client().get(f"/study/demo/start?pid=a{i}").status_code == 302
    r = app.test_client().get("/study/demo/start?pid=a3")
    assert r.status_code == 429 and b"Too many people" in r.data
    far = app.test_client()
    far.environ_base["REMOTE_ADDR"] = "10.1.2.3"  # another address is not held back
    b = to_trials(far, query="pid=elsewhere")
    assert post_events(far, b, [event(i) for i in range(60)]).status_code == 200
    assert post_events(far, b, [event(i) for i in range(60)]).status_code == 200  # a resend adds nothing
    assert post_events(far, b, [event(i) for i in range(50, 100)]).status_code == 200  # ten of them again
    with app.app_context():
        p = db.session.query(Participant).filter_by(platform_id="elsewhere").one()
        assert (p.events_stored, p.acked_seq) == (100, 99) and 0 < p.bytes_stored < 100 * 200
    r = post_events(far, b, [event(100)])
    assert r.status_code == 429 and r.headers["Retry-After"] and r.json["field"] == "events"
    c = app.test_client()
    c.environ_base["REMOTE_ADDR"] = "10.1.2.4"
    b = to_trials(c, query="pid=bytes")
    payload = "x" * 1900
    codes = [post_events(c, b, [event(j * 50 + i, text=payload) for i in range(50)]).status_code for j in range(3)]
    assert codes == [200, 200, 429]  # 0.2 MB: two batches of 50 × 2 kB, not a third


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


def test_an_event_another_tab_already_stored_under_a_new_seq_is_acknowledged(app_on):
    c = app_on.test_client()
    b = to_trials(c)
    mine = event(0, text="mine")
    assert post_events(c, b, [event(0, text="theirs"), dict(mine, seq=1)]).json["acked_seq"] == 1
    r = post_events(c, b, [mine])  # this page still holds it under its first seq
    assert r.status_code == 200 and r.json["acked_seq"] == 1
    with app_on.app_context():
        assert db.session.query(Event).count() == 2
