"""Participants are told when the interface changes: before the first trial and before every trial whose condition
differs from the one before, a page with the condition's instructions that the participant dismisses; it is
logged (session log, an event the replay shows, the export's trials) and its time is not trial time."""

from __future__ import annotations

import json
from datetime import timedelta

from flowhelp import DEMOGRAPHICS, auth
from sqlalchemy import select

from scenesuggest.contract.events import validate_batch
from simulation.page import read_page
from simulation.transport import FlaskTransport
from simulation.walker import Walker, fixed_answer
from study_server.base.extensions import db
from study_server.base.models import Event, Participant, SessionLog, Trial
from study_server.trials.replays import label


def _walk_to_briefing(client, headers=None):
    walker = Walker(FlaskTransport(client), "demo")
    page = walker.enter("pid=brief-1", headers={"User-Agent": "Mozilla/5.0 (X11; Linux x86_64) Chrome/150",
                                                **(headers or {})})
    return walker, walker.walk(lambda _: DEMOGRAPHICS, until=("briefing", "trial"), page=page)


def _plan(app) -> list[Trial]:
    with app.app_context():
        p = db.session.scalar(select(Participant).where(Participant.platform_id == "brief-1"))
        return list(db.session.scalars(select(Trial).where(Trial.participant_id == p.id).order_by(Trial.position)))


def _finish(client, b: dict, seq: int) -> int:
    t = b["trial"]
    events = [{"seq": seq, "t": 1.0e12 + seq * 1e5, "type": "trial_start", "trial": t["index"],
               "payload": {"scene": t["scene"], "condition": t["condition"]}}]
    assert client.post("/api/events", headers=auth(b), json={"page_id": b["page_id"], "events": events}).status_code \
        == 200
    assert client.post("/api/trial/done", headers=auth(b), json={"trial": t["index"]}).status_code == 200
    return seq + 1


def test_the_condition_is_explained_before_the_first_trial_and_wherever_it_changes(client, app):
    study = app.extensions["studies"]["demo"].study
    walker, page = _walk_to_briefing(client)
    plan = _plan(app)
    seq, briefed = 0, []
    for t in plan:
        assert page.step == ("briefing" if t.position == 0 or plan[t.position - 1].condition != t.condition
                             else "trial"), t.position
        if page.step == "briefing":
            html = client.get("/study/demo/").get_data(as_text=True)  # a reload shows it again, its clock kept
            condition = study.condition(t.condition)
            assert str(condition.label) in html and str(condition.instructions).split(".")[0] in html
            assert ("Before you start" in html) == (t.position == 0)
            assert ("you add objects in a different way" in html) == (t.position > 0)
            briefed.append(t.position)
            page = walker.submit("briefing", fixed_answer(page), page)
        assert page.step == "trial" and page.boot["trial"]["index"] == t.index
        seconds = page.boot["trial"]["briefing"]
        assert (seconds is not None) == (t.position in briefed) and (seconds is None or seconds >= 0)
        seq = _finish(client, page.boot, seq)
        page = walker.current()
    assert page.step == "exit"
    assert len(briefed) == 1 + len({t.block for t in plan if t.kind == "trial"})  # the practice and each block
    with app.app_context():
        shown = db.session.scalars(select(SessionLog).where(SessionLog.kind == "briefing_shown")).all()
        read = db.session.scalars(select(SessionLog).where(SessionLog.kind == "briefing_read")).all()
        assert [r.detail["position"] for r in shown] == [r.detail["position"] for r in read] == briefed
    for t in _plan(app):
        if t.position in briefed:  # the trial began after the instructions were dismissed: not trial time
            assert t.briefing_shown_at <= t.briefed_at <= t.started_at
        else:
            assert t.briefing_shown_at is None and t.briefed_at is None


def test_a_repeated_stale_or_blind_dismissal_changes_nothing(client, app):
    walker, page = _walk_to_briefing(client)
    token = page.csrf
    assert page.hidden == {"position": "0"}  # the page says whose instructions it shows
    for blind in ({}, {"position": "1"}, {"position": "-1"}, {"position": "x" * 20}, {"position": "9" * 40},
                  {"position": "²"}, {"position": "①"}, {"position": "٠"}, {"position": "0 "}):
        assert client.post("/study/demo/briefing", data={"csrf_token": token, **blind}).status_code == 302
        assert _plan(app)[0].briefed_at is None  # not the instructions shown: nothing dismissed
    first = walker.submit("briefing", fixed_answer(page), page)
    assert first.step == "trial"
    (t0, *_) = _plan(app)
    assert t0.briefed_at is not None and t0.started_at is not None
    before = t0.briefed_at
    again = client.post("/study/demo/briefing", data={"csrf_token": token, "position": "0"})  # a resubmitted form
    assert again.status_code == 302 and _plan(app)[0].briefed_at == before
    # without the form token nothing moves
    assert client.post("/study/demo/briefing", data={"position": "0"}).status_code == 400


def test_instructions_never_shown_are_never_dismissed_and_hold_the_trial(client, app):
    """The next condition's instructions must have been shown before they can be dismissed, and a trial whose
    instructions are due cannot be finished over the API (a page never skips them; a script may not either)."""
    walker, page = _walk_to_briefing(client)
    token = page.csrf
    page = walker.submit("briefing", fixed_answer(page), page)
    b = page.boot
    seq = _finish(client, b, 0)  # the practice
    plan = _plan(app)
    assert plan[1].condition != plan[0].condition  # the next trial's instructions are due, not yet shown
    assert client.post("/study/demo/briefing", data={"csrf_token": token, "position": "1"}).status_code == 302
    assert _plan(app)[1].briefed_at is None  # never shown: not dismissed
    done = client.post("/api/trial/done", headers=auth(b), json={"trial": plan[1].index})
    assert done.status_code == 409 and "instructions come first" in done.json["error"]
    page = walker.current()
    assert page.step == "briefing"
    page = walker.submit("briefing", fixed_answer(page), page)
    assert page.step == "trial" and _finish(client, page.boot, seq) == seq + 1


def test_the_briefing_speaks_the_participants_language(client, app):
    _, page = _walk_to_briefing(client, headers={"Accept-Language": "de-DE,de;q=0.9"})
    assert page.step == "briefing"
    html = client.get("/study/demo/").get_data(as_text=True)
    condition = app.extensions["studies"]["demo"].study.condition(_plan(app)[0].condition)
    assert condition.label.in_language("de") in html
    assert condition.instructions.in_language("de").split(".")[0] in html
    assert "Bevor Sie beginnen" in html and "Diese Szene beginnen" in html and 'lang="de"' in html


def test_the_briefing_is_an_event_of_the_trial_that_the_replay_shows():
    event = {"seq": 0, "t": 1.7e12, "type": "briefing", "trial": 0, "payload": {"condition": "none", "seconds": 12.5}}
    validate_batch([event])
    assert label(event) == "read the instructions of none (12 s, before the trial)"


def test_the_export_says_how_long_each_briefing_was_open(client, app, tmp_path):
    import pandas as pd

    from study_server.experimenter.export import export_to

    walker, page = _walk_to_briefing(client)
    page = walker.submit("briefing", {"go": "start"}, page)
    with app.app_context():
        t = db.session.scalar(select(Trial).where(Trial.position == 0))
        t.briefed_at = t.briefing_shown_at + timedelta(seconds=7.25)
        db.session.commit()
        export_to(app.extensions["studies"]["demo"], tmp_path / "export")
    trials = pd.read_csv(tmp_path / "export" / "trials.csv")
    assert trials.loc[trials["position"] == 0, "briefing_seconds"].tolist() == [7.25]
    assert trials.loc[trials["position"] > 0, "briefing_seconds"].isna().all()
    assert read_page(client.get("/study/demo/").data).step == "trial"


def test_hostile_values_for_the_briefing_change_nothing_and_get_a_clear_answer(client, app):
    """Whatever a browser can send as the instructions' form or the briefing event: a 4xx naming what is wrong
    (or, for the form, nothing dismissed), nothing stored, no 500."""
    walker, page = _walk_to_briefing(client)
    token = page.csrf
    for position in ("\x00", "0\x00", "2147483648", "1" * 100, "0" * 8 + "0", "\ufffd"):
        r = client.post("/study/demo/briefing", data={"csrf_token": token, "position": position})
        assert r.status_code == 302 and _plan(app)[0].briefed_at is None, position
    huge = client.post("/study/demo/briefing", data={"csrf_token": token, "position": "0" * 10_000_000})
    assert huge.status_code == 413 and _plan(app)[0].briefed_at is None
    page = walker.submit("briefing", fixed_answer(page), page)
    b = page.boot
    with app.app_context():
        before = db.session.query(Event).count()
    for payload, field in (({"condition": "none", "seconds": -1}, "seconds"),
                           ({"condition": "none", "seconds": "12"}, "seconds"),
                           ({"condition": "none", "seconds": True}, "seconds"),
                           ({"condition": "none", "seconds": 2**1100}, "seconds"),
                           ({"condition": "other", "seconds": 1}, "condition"),
                           ({"condition": "none\x00", "seconds": 1}, "condition"),
                           ({"condition": "\ud800", "seconds": 1}, "condition"),
                           ({"condition": "n" * 3_000_000, "seconds": 1}, None),
                           ({"seconds": 1}, "condition")):
        event = {"seq": 0, "t": 1.7e12, "type": "briefing", "trial": -1, "payload": payload}
        body = json.dumps({"page_id": b["page_id"], "events": [event]}).encode()  # (a lone surrogate, escaped)
        r = client.post("/api/events", headers={**auth(b), "Content-Type": "application/json"}, data=body)
        if field is None:  # over the body's limit
            assert r.status_code == 413 and r.json["field"] == "body"
        else:
            assert r.status_code == 422 and r.json["field"] == f"events[0].payload.{field}", (payload, r.json)
    with app.app_context():
        assert db.session.query(Event).count() == before  # nothing stored
