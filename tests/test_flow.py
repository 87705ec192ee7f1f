"""A participant's whole run with HTTP requests alone, and the ways out and back in."""

import pytest
from flowhelp import DEMOGRAPHICS, EXIT, auth, boot, csrf, enter, finish_all_trials, to_trials

from simulation.walker import CAPABLE_DEVICE
from study_server.base.extensions import db
from study_server.base.models import Event, Participant, SessionLog, SurveyResponse, Trial


def test_a_whole_run_of_the_demo_study(client, app):
    b = to_trials(client)
    assert b["trial"]["kind"] == "practice" and b["trial"]["condition"] == "full"
    seen = finish_all_trials(client, b)
    assert [s["trial"]["index"] for s in seen] == list(range(-1, 9))
    conditions = [s["trial"]["condition"] for s in seen[1:]]
    assert sorted(conditions) == sorted(["none", "basic", "full"] * 3)
    page = client.get("/study/demo/")
    assert b"Almost done" in page.data
    r = client.post("/study/demo/exit", data={"csrf_token": csrf(page), **EXIT, "last_seq": "29", "attempt": "0"})
    assert r.status_code == 302
    done = client.get("/study/demo/")
    assert b"DEMO-DONE-7F3A" in done.data
    with app.app_context():
        p = db.session.query(Participant).one()
        assert p.status == "completed" and p.code == "DEMO-DONE-7F3A" and p.acked_seq == 29 and p.flags == []
        assert p.consent_version == "demo-2026-11" and p.study_hash == app.extensions["studies"]["demo"].study.hash
        assert db.session.query(Event).count() == 30
        assert all(t.done_at is not None for t in db.session.query(Trial).filter_by(participant_id=p.id))
        answers = {s.survey: s.answers for s in db.session.query(SurveyResponse)}
        assert answers["demographics"] == {"age": 31, "experience_3d": "Never", "pointing_device": "Trackpad"}
        assert answers["exit"]["enjoy_suggestions"] == 5 and answers["exit"]["preference"] == "Suggestions, oriented"


def test_every_page_says_its_step_and_one_walker_goes_through_them(client):
    """Pages mark their step (``<body data-step>``): the walker reads the step, the form token, the trial's boot
    data and the completion code without looking at wording or markup."""
    from simulation.page import read_page
    from simulation.transport import FlaskTransport
    from simulation.walker import Walker

    seen = []

    def answers(page):
        seen.append(page.step)
        return DEMOGRAPHICS if page.step == "demographics" else {**EXIT, "last_seq": "29", "attempt": "0"}

    walker = Walker(FlaskTransport(client), "demo")
    first = walker.enter("pid=walker")
    assert first.step == "device" and first.csrf
    trials = []
    b = walker.walk(answers, page=first).boot
    assert b is not None and b["trial"]["kind"] == "practice"
    finish_all_trials(client, b)
    # an exit survey sent before the server has every event ends the walk on the waiting page, without a code
    waiting = walker.walk(lambda page: {**answers(page), "last_seq": "35"})
    assert waiting.step == "saving" and waiting.code is None and waiting.hidden["attempt"] == "1"
    end = walker.walk(answers, lambda boot: trials.append(boot) or True)
    assert seen == ["demographics", "exit", "exit"] and trials == []
    assert end.step == "done" and end.code == "DEMO-DONE-7F3A"
    assert read_page(client.get("/study/nope/").data).step == "message"  # a calm notice, not a step of the flow
    assert read_page(enter(client.application.test_client(), query="pid=other").data).step == "device"


def test_the_completion_code_waits_for_the_last_events(client, app):
    b = to_trials(client)
    finish_all_trials(client, b)
    page = client.get("/study/demo/")
    # the client says its last event is seq 35, but the server holds up to 29: not complete yet
    r = client.post("/study/demo/exit", data={"csrf_token": csrf(page), **EXIT, "last_seq": "35", "attempt": "0"})
    assert r.status_code == 202 and b"Saving your work" in r.data and b'name="attempt" value="1"' in r.data
    events = [{"seq": s, "t": 1.0, "type": "focus", "trial": None, "payload": {"state": "blur"}} for s in range(30, 36)]
    client.post("/api/events", headers=auth(b), json={"page_id": "exit", "events": events})
    r = client.post("/study/demo/exit", data={"csrf_token": csrf(page), **EXIT, "last_seq": "35", "attempt": "1"})
    assert r.status_code == 302 and b"DEMO-DONE" in client.get("/study/demo/").data


def test_the_exit_pages_flush_to_the_api_below_the_apps_mount_point(client, app):
    """The exit survey and the saving page send the last events where the API is, as the editor does: below
    the mount point when the app is served under a path."""
    b = to_trials(client)
    finish_all_trials(client, b)
    assert 'data-api="/api"' in client.get("/study/demo/").get_data(as_text=True)
    assert 'data-api="/lab/api"' in client.get("/study/demo/", environ_overrides={"SCRIPT_NAME": "/lab"}
                                               ).get_data(as_text=True)
    page = client.get("/study/demo/")
    saving = client.post("/study/demo/exit", data={"csrf_token": csrf(page), **EXIT, "last_seq": "99", "attempt": "0"},
                         environ_overrides={"SCRIPT_NAME": "/lab"})
    assert saving.status_code == 202 and 'data-api="/lab/api"' in saving.get_data(as_text=True)


def test_when_the_network_is_gone_the_code_comes_after_a_few_attempts(client, app):
    b = to_trials(client)
    finish_all_trials(client, b)
    page = client.get("/study/demo/")
    r = client.post("/study/demo/exit", data={"csrf_token": csrf(page), **EXIT, "last_seq": "40", "attempt": "5"})
    assert r.status_code == 302 and b"DEMO-DONE" in client.get("/study/demo/").data
    with app.app_context():
        assert db.session.query(SessionLog).filter_by(kind="completed_with_missing_events").count() == 1


def test_declining_consent_and_failing_the_device_check_end_with_their_codes(client, app):
    page = enter(client, query="pid=decliner")
    client.post("/study/demo/device", data={**CAPABLE_DEVICE, "csrf_token": csrf(page)})
    client.post("/study/demo/consent", data={"csrf_token": csrf(page), "agree": "no"})
    assert b"DEMO-NOCONSENT" in client.get("/study/demo/").data

    phone = client.application.test_client()
    page = enter(phone, query="pid=phone", ua="Mozilla/5.0 (iPhone; CPU iPhone OS 17_0) Mobile Safari")
    phone.post("/study/demo/device", data={**CAPABLE_DEVICE, "csrf_token": csrf(page)})
    assert b"DEMO-SCREENED" in phone.get("/study/demo/").data

    small = client.application.test_client()
    page = enter(small, query="pid=small")
    small.post("/study/demo/device", data={**CAPABLE_DEVICE, "csrf_token": csrf(page), "width": "800"})
    assert b"DEMO-SCREENED" in small.get("/study/demo/").data
    with app.app_context():
        assert {p.platform_id: p.status for p in db.session.query(Participant)} == {
            "decliner": "no_consent", "phone": "screened_out", "small": "screened_out"}


def test_survey_answers_are_checked_and_kept_on_error(client):
    page = enter(client)
    client.post("/study/demo/device", data={**CAPABLE_DEVICE, "csrf_token": csrf(page)})
    client.post("/study/demo/consent", data={"csrf_token": csrf(page), "agree": "yes"})
    r = client.post("/study/demo/demographics", data={"csrf_token": csrf(page), "age": "12",
                                                      "experience_3d": "Daily", "pointing_device": "Mouse"})
    assert r.status_code == 422
    assert b"between 18 and 100" in r.data and b"choose one of the options" in r.data
    assert b'value="Mouse" checked' in r.data
    r = client.post("/study/demo/demographics", data={"csrf_token": csrf(page), **DEMOGRAPHICS})
    assert r.status_code == 302


def test_forms_need_their_csrf_token(client, app):
    enter(client)
    r = client.post("/study/demo/device", data={**CAPABLE_DEVICE, "width": "1400", "height": "900"})
    assert r.status_code == 400 and b"expired" in r.data
    with app.app_context():
        assert db.session.query(Participant).one().step == "device"


def test_reload_back_button_and_second_tab_resume_and_are_logged(client, app):
    b = to_trials(client)
    first = client.get("/study/demo/")  # reload
    assert boot(first)["trial"] == b["trial"]
    # the back button re-posts nothing: an old form sent again does not move the participant backwards
    client.post("/study/demo/consent", data={"csrf_token": client.form_token, "agree": "no"})
    again = client.get("/study/demo/")
    assert boot(again)["trial"] == b["trial"]
    # the same platform id arriving again (a second tab, or the link opened twice) gets the same session
    r = client.get("/study/demo/start?pid=p1")
    assert r.status_code == 302
    with app.app_context():
        p = db.session.query(Participant).one()
        assert p.status == "in_progress" and p.step == "trial"
        resumes = [row.detail.get("times", 1) for row in db.session.query(SessionLog).filter_by(participant_id=p.id)
                   if row.kind == "resume"]
        assert sum(resumes) >= 3  # reloads of one place count on one row


def test_platform_entry_parameters(app):
    from demostudy import DEMO_STUDY  # noqa: F401  (documentation of which study is used)

    c = app.test_client()
    r = c.get("/study/demo/start")  # a link study without pid gets an anonymous id, remembered by the browser
    assert r.status_code == 302
    again = c.get("/study/demo/start")
    assert again.status_code == 302
    with app.app_context():
        assert db.session.query(Participant).count() == 1
        assert db.session.query(Participant).one().platform_id.startswith("link-")
    assert c.get("/study/nope/start?pid=x").status_code == 404
    assert b"Please start this study" in app.test_client().get("/study/demo/").data


@pytest.fixture
def platform_app(tmp_path, demo_resources):
    """The demo study as a Prolific and as an MTurk study."""
    from demostudy import make_app

    def make(kind):
        text = demo_resources.read_text().replace('kind = "link"', f'kind = "{kind}"\ncompletion_url = '
                                                   '"https://app.prolific.com/submissions/complete?cc={code}"')
        text = text.replace('target = "scenes/', f'target = "{demo_resources.parent}/scenes/')
        path = tmp_path / f"{kind}.toml"
        path.write_text(text)
        return make_app(tmp_path / kind, studies=[path])
    return make


PID, STUDY, SESSION = "5f3a" + "0" * 20, "6a1b" + "1" * 20, "7c2d" + "2" * 20  # Prolific ids: 24 hex digits


def test_prolific_parameters_are_required_and_stored(platform_app):
    app = platform_app("prolific")
    c = app.test_client()
    r = c.get(f"/study/demo/start?STUDY_ID={STUDY}")
    assert r.status_code == 422 and b"PROLIFIC_PID is missing" in r.data
    page = enter(c, query=f"PROLIFIC_PID={PID}&STUDY_ID={STUDY}&SESSION_ID={SESSION}")
    assert b"device-form" in page.data
    with app.app_context():
        p = db.session.query(Participant).one()
        assert (p.platform, p.platform_id, p.platform_meta["SESSION_ID"]) == ("prolific", PID, SESSION)


WORKER, ASSIGNMENT, HIT = "A1B2C3D4E5F6G7", "3AMW0RGHOD1P" + "0" * 18, "3HYA4D452RIC" + "1" * 18


def test_mturk_preview_mode_creates_nobody(platform_app):
    app = platform_app("mturk")
    c = app.test_client()
    r = c.get("/study/demo/start?assignmentId=ASSIGNMENT_ID_NOT_AVAILABLE&hitId=h")
    assert r.status_code == 200 and b"Accept the HIT" in r.data
    with app.app_context():
        assert db.session.query(Participant).count() == 0
    enter(c, query=f"workerId={WORKER}&assignmentId={ASSIGNMENT}&hitId={HIT}&turkSubmitTo=https://www.mturk.com")
    with app.app_context():
        assert db.session.query(Participant).one().platform_meta["assignmentId"] == ASSIGNMENT


def test_failures_show_a_friendly_page_and_are_logged(client, app, monkeypatch):
    from study_server.participants import flow

    to_trials(client)

    def broken(*args):
        raise RuntimeError("disk on fire")
    monkeypatch.setattr(flow, "check_session_time", broken)
    r = client.get("/study/demo/")
    assert r.status_code == 500 and b"Your work is saved" in r.data and b"Traceback" not in r.data
    assert b"disk on fire" not in r.data
    with app.app_context():
        row = db.session.query(SessionLog).filter_by(kind="error").one()
        assert row.detail["error"] == "RuntimeError" and row.detail["reference"].encode() in r.data


def test_a_page_reads_its_participant_once_and_writes_at_its_commit(client, app):
    """A page view's statements: the participant read once (the page's language and the view share it), every
    write flushed at the commit (SQLite's write lock is not held while the page is made), one commit, nothing read
    again after it; a trial page (reloaded) the same."""
    import re

    from sqlalchemy import event

    enter(client)
    with app.app_context():
        engine = db.engine
    statements: list[str] = []

    def seen(conn, cursor, statement, *args):
        verb = statement.split()[0].upper()
        table = re.search(r"(?:FROM|INTO|UPDATE)\s+(\w+)", statement, re.IGNORECASE)
        statements.append(f"{verb} {table.group(1) if table else ''}")

    def committed(conn):
        statements.append("COMMIT")

    event.listen(engine, "before_cursor_execute", seen)
    event.listen(engine, "commit", committed)
    try:
        for expected in ("device", "trial"):
            if expected == "trial":
                to_trials(client)  # the same browser, resumed and walked to its first trial
            statements.clear()
            assert f'data-step="{expected}"'.encode() in client.get("/study/demo/").data
            assert statements.count("SELECT participants") == 1, statements
            assert statements.count("COMMIT") == 1 and statements[-1] == "COMMIT", statements
            verbs = [s.split()[0] for s in statements]
            first_write = min(i for i, v in enumerate(verbs) if v in ("INSERT", "UPDATE"))
            assert "SELECT" not in verbs[first_write:], statements
    finally:
        event.remove(engine, "before_cursor_execute", seen)
        event.remove(engine, "commit", committed)
