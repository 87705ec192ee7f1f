"""The server's check of a trial at "done": events of each vocabulary stored, the trial rebuilt from them and scored
against its target, a check that waits for late events (made when they arrive, or at completion), the closeness
the export gives, and a check that fails never holding the participant up."""


import pytest
from flowhelp import EXIT, auth, csrf, finish_all_trials, next_trial, to_trials
from statehelp import event, insert, obj

from study_server.base.extensions import db
from study_server.base.models import Event, Participant, Trial


def test_batches_say_their_vocabulary_and_old_pages_still_store(client, app):
    b = to_trials(client)
    h = auth(b)
    old = {"seq": 0, "t": 1.7e12, "type": "insert", "trial": -1,
           "payload": {"object": "a", "model": "m", "category": "C", "rank": 1, "source": "fixed"}}
    assert client.post("/api/events", headers=h, json={"page_id": "p", "events": [old]}).status_code == 200
    r = client.post("/api/events", headers=h, json={"page_id": "p", "vocabulary": 2,
                                                    "events": [{**old, "seq": 1}]})
    assert r.status_code == 422 and r.json["field"] == "events[0].payload.objects"
    r = client.post("/api/events", headers=h, json={"page_id": "p", "vocabulary": 3, "events": []})
    assert r.status_code == 422 and r.json["field"] == "vocabulary"
    new = {**insert(1, obj("a")), "trial": -1}
    assert client.post("/api/events", headers=h, json={"page_id": "p", "vocabulary": 2,
                                                     "events": [new]}).status_code == 200
    with app.app_context():
        assert [(e.seq, e.vocabulary) for e in db.session.query(Event).order_by(Event.seq)] == [(0, 1), (1, 2)]


def _finish(client, b, events, scene):
    r = client.post("/api/events", headers=auth(b), json={"page_id": "p", "vocabulary": 2, "events": events})
    assert r.status_code == 200, r.json
    assert client.post("/api/trial/done", headers=auth(b), json={"trial": b["trial"]["index"],
                                                                   "scene": {"objects": scene}}).status_code == 200


def test_done_replays_the_trial_and_scores_it_against_its_target(client, app):
    b = to_trials(client)  # the practice: a dining table with a plate, an apple and a bowl on it
    rt = app.extensions["studies"]["demo"]
    start = rt.scene(b["trial"]["scene"], "start")["objects"]
    target = [o for o in rt.scene(b["trial"]["scene"], "target")["objects"] if o["parent"] is not None]
    events = [{**insert(i, o), "trial": -1} for i, o in enumerate(target)]
    _finish(client, b, events, start + target)
    with app.app_context():
        t = db.session.query(Trial).filter_by(index=-1).one()
        assert t.replay == "match" and t.score == pytest.approx(1.0)
    b2 = next_trial(client)
    nudged = [{**target[0], "transform": target[0]["transform"][:12] + [9.0, 0.0, 9.0, 1.0]}]
    _finish(client, b2, [{**insert(100, nudged[0]), "trial": b2["trial"]["index"]}],
            rt.scene(b2["trial"]["scene"], "start")["objects"] + [target[0]])  # not what its events built
    with app.app_context():
        t = db.session.query(Trial).filter_by(index=b2["trial"]["index"]).one()
        assert t.replay.startswith("mismatch: ") and "transform differs" in t.replay
        assert t.score == 0.0 and "close to the target < 0.3" in t.review  # a table top's plate is no sofa's


@pytest.mark.parametrize("column", [True, False], ids=["waiting in its column", "waiting in prose only"])
def test_a_check_waits_for_late_events_and_a_low_score_stays_flagged_after_completion(client, app, column):
    """'done' can arrive before the page's last events (their request failed, 'done' did not): the check waits
    for them (``pending``) and is made when they are stored; the flag of a low score outlives the work check
    at completion. A wait that an app server of the version before the column wrote (in prose only, as during an
    upgrade with two servers) is made too."""
    b = to_trials(client)
    rt = app.extensions["studies"]["demo"]
    _finish(client, b, [], rt.scene(b["trial"]["scene"], "start")["objects"])  # the practice, left empty
    t = next_trial(client)["trial"]
    target = [o for o in rt.scene(t["scene"], "target")["objects"] if o["parent"] is not None]
    far = {**target[0], "transform": target[0]["transform"][:12] + [9.0, 0.0, 9.0, 1.0]}
    scene = rt.scene(t["scene"], "start")["objects"] + [far]
    r = client.post("/api/events", headers=auth(b), json={"page_id": "p", "vocabulary": 2,
                                                        "events": [{**insert(0, far), "trial": t["index"]}]})
    assert r.status_code == 200
    r = client.post("/api/trial/done", headers=auth(b), json={"trial": t["index"], "scene": {"objects": scene},
                                                               "last_seq": 1})
    assert r.status_code == 200
    with app.app_context():
        done = db.session.query(Trial).filter_by(index=t["index"]).one()
        assert done.replay == "pending: events up to seq 1 not stored yet" and done.score == 0.0
        assert done.replay_waits_for == 1
        if not column:
            done.replay_waits_for = None
            db.session.commit()
    late = {**event(1, "camera", action="orbit"), "trial": t["index"]}
    assert client.post("/api/events", headers=auth(b), json={"page_id": "p", "vocabulary": 2,
                                                            "events": [late]}).status_code == 200
    finish_all_trials(client, next_trial(client), first_seq=2)  # the next 'done' makes the check
    with app.app_context():
        settled = db.session.query(Trial).filter_by(index=t["index"]).one()
        assert settled.replay == "match" and settled.replay_waits_for is None
    page = client.get("/study/demo/")
    r = client.post("/study/demo/exit", data={"csrf_token": csrf(page), **EXIT, "last_seq": "25", "attempt": "0"})
    assert r.status_code == 302
    with app.app_context():
        assert db.session.query(Participant).one().status == "completed"
        done = db.session.query(Trial).filter_by(index=t["index"]).one()
        assert done.replay == "match"
        assert done.review == "1 s of events < 10 s, scene 0.00 close to the target < 0.3"


def test_the_export_gives_the_closeness_found_at_done_and_scores_older_trials_itself(client, app, monkeypatch):
    """What the database holds and what an export gives cannot drift apart when the scoring code changes: the whole
    closeness result is stored at "done" and exported as stored; a trial done before it was stored (no result) is
    scored by the export."""
    from study_server.experimenter import export
    from study_server.trials import trial_check

    b = to_trials(client)
    rt = app.extensions["studies"]["demo"]
    start = rt.scene(b["trial"]["scene"], "start")["objects"]
    target = [o for o in rt.scene(b["trial"]["scene"], "target")["objects"] if o["parent"] is not None]
    _finish(client, b, [{**insert(i, o), "trial": -1} for i, o in enumerate(target)], start + target)
    with app.app_context():
        t = db.session.query(Trial).filter_by(index=-1).one()
        assert t.closeness["score"] == t.score == pytest.approx(1.0)
        assert t.closeness["matched"] == len(target) and len(t.closeness["matches"]) == len(target)
        monkeypatch.setattr(trial_check, "closeness", lambda *_: pytest.fail("the export rescored a stored trial"))
        row = next(r for r in export._table(rt, "trials", {}) if r["trial"] == -1)
        assert (row["score"], row["matched"], row["missing"]) == (pytest.approx(1.0), len(target), 0)
        t.closeness = None  # as a trial done before the result was stored
        monkeypatch.undo()
        row = next(r for r in export._table(rt, "trials", {}) if r["trial"] == -1)
        assert row["score"] == pytest.approx(1.0) and row["position_error_m"] == pytest.approx(0.0, abs=1e-9)
        t.closeness = {"unavailable": "the check failed"}
        row = next(r for r in export._table(rt, "trials", {}) if r["trial"] == -1)
        assert row["score"] == row["matched"] == row["orientation_error_deg"] == ""


def test_a_check_that_fails_never_holds_the_participant_up(client, app, monkeypatch):
    from study_server.trials import trial_check

    def broken(*_):
        raise RuntimeError("a mesh that cannot be read")

    monkeypatch.setattr(trial_check, "target_closeness", broken)
    b = to_trials(client)
    start = app.extensions["studies"]["demo"].scene(b["trial"]["scene"], "start")["objects"]
    _finish(client, b, [], start)
    assert next_trial(client)["trial"]["index"] == 0  # on to the first trial
    with app.app_context():
        practice = db.session.query(Trial).filter_by(index=-1).one()
        assert practice.replay == "match" and practice.score is None  # the replay check stands; no score
        assert practice.closeness == {"unavailable": "the check failed"}


def test_a_check_waiting_for_events_that_never_come_is_made_at_completion(client, app, monkeypatch):
    """A page that says it logged more than it ever sends (or loses its last events for good) cannot keep its
    trial's check pending: at completion the check is made on what is stored, and says so; a check that fails
    there does not stop the participant completing."""
    from study_server.trials import trial_check

    b = to_trials(client)
    rt = app.extensions["studies"]["demo"]
    start = rt.scene(b["trial"]["scene"], "start")["objects"]
    r = client.post("/api/trial/done", headers=auth(b), json={"trial": -1, "scene": {"objects": start},
                                                               "last_seq": 2**31 - 1})
    assert r.status_code == 200
    finish_all_trials(client, next_trial(client), first_seq=0)
    with app.app_context():
        assert db.session.query(Trial).filter_by(index=-1).one().replay.startswith("pending: ")
    calls = []
    real = trial_check.replay_check

    def fails_once(*args):
        calls.append(1)
        if len(calls) == 1:
            raise RuntimeError("a scene file gone")
        return real(*args)

    monkeypatch.setattr(trial_check, "replay_check", fails_once)
    page = client.get("/study/demo/")
    r = client.post("/study/demo/exit", data={"csrf_token": csrf(page), **EXIT, "last_seq": "26", "attempt": "0"})
    assert r.status_code == 302
    with app.app_context():
        assert db.session.query(Participant).one().status == "completed"
        practice = db.session.query(Trial).filter_by(index=-1).one()
        assert practice.replay == "unavailable: the check failed (events after seq 26 never arrived)"
