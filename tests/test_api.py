"""The JSON API: authorisation, lossless idempotent ingestion, suggestions per condition, lists logged."""

import json
from concurrent.futures import ThreadPoolExecutor

import pytest
from flowhelp import auth, next_trial, to_trials

from scenesuggest.scenes import scene_json
from study_server.base.extensions import db
from study_server.base.models import Event, Participant, ShownList, Trial


def ev(seq, kind="focus", trial=None, **payload):
    return {"seq": seq, "t": 1.7e12 + seq, "type": kind, "trial": trial, "payload": payload or {"state": "blur"}}


def walk_to(client, app, condition: str, pid: str = "p1") -> dict:
    """Finish trials until the current one has ``condition``; returns its boot data."""
    b = to_trials(client, query=f"pid={pid}")
    while b["trial"]["condition"] != condition or b["trial"]["kind"] == "practice":
        client.post("/api/trial/done", headers=auth(b), json={"trial": b["trial"]["index"]})
        b = next_trial(client)
    return b


def test_tokens_are_required_and_scoped(client, app):
    b = to_trials(client)
    assert client.get("/api/session").status_code == 401
    assert client.get("/api/session", headers={"Authorization": "Bearer nope"}).status_code == 401
    r = client.get("/api/session", headers={"Authorization": "Bearer " + "x" * 500})
    assert r.status_code == 401 and r.json["field"] == "Authorization"
    other = app.test_client()
    ob = to_trials(other, query="pid=someone-else")
    # each token sees its own session; a scene outside one's own plan is not served
    mine = client.get("/api/session", headers=auth(b)).json["trial"]
    assert (mine["index"], mine["scene"], mine["condition"]) == (-1, "practice", "full")
    assert other.get("/api/scenes/desk-corner", headers=auth(ob)).status_code == 200
    assert client.get("/api/scenes/../../etc/passwd", headers=auth(b)).status_code == 404
    assert client.get("/api/scenes/attic", headers=auth(b)).status_code == 404
    # events are stored under the token's participant only
    client.post("/api/events", headers=auth(b), json={"page_id": "p", "events": [ev(0)]})
    with app.app_context():
        owners = {e.participant_id for e in db.session.query(Event)}
        me = db.session.query(Participant).filter_by(platform_id="p1").one()
        assert owners == {me.id}


def test_ingestion_is_idempotent_and_acknowledges_contiguous_seqs(client, app):
    b = to_trials(client)
    post = lambda events: client.post("/api/events", headers=auth(b), json={"page_id": "p1", "events": events})  # noqa: E731
    assert post([ev(0), ev(1), ev(2)]).json["acked_seq"] == 2
    assert post([ev(1), ev(2)]).json["acked_seq"] == 2  # a retry stores nothing twice
    assert post([ev(5), ev(6)]).json["acked_seq"] == 2  # a gap: not acknowledged beyond it
    assert post([ev(3), ev(4)]).json["acked_seq"] == 6  # the gap filled
    assert post([]).json["acked_seq"] == 6
    with app.app_context():
        assert sorted(e.seq for e in db.session.query(Event)) == list(range(7))


def test_parallel_duplicate_batches_store_each_event_once(client, app):
    b = to_trials(client)
    batches = [[ev(s) for s in range(k, k + 50)] for k in range(0, 500, 50)]

    def send(batch):
        c = app.test_client()
        return c.post("/api/events", headers=auth(b), json={"page_id": "p", "events": batch}).status_code
    with ThreadPoolExecutor(max_workers=8) as pool:
        codes = list(pool.map(send, batches + batches[::-1] + batches))
    assert set(codes) == {200}
    with app.app_context():
        seqs = [e.seq for e in db.session.query(Event)]
        assert sorted(seqs) == list(range(500))
        assert db.session.query(Participant).filter_by(platform_id="p1").one().acked_seq == 499


@pytest.mark.parametrize(("events", "field"), [
    ([ev(0, kind="teleport")], "events[0].type"),
    ([{"seq": -1, "t": 1.0, "type": "focus", "payload": {"state": "blur"}}], "events[0].seq"),
    ([{"seq": 0, "t": "soon", "type": "focus", "payload": {"state": "blur"}}], "events[0].t"),
    ([ev(0), ev(1, kind="insert", object="o1", model="m", category="C", rank=0, source="context")],
     "events[1].payload.rank"),
    ([ev(0, kind="rotate_end", object="o1", angle=float("nan"))], None),
    ([ev(0, kind="focus", state="sideways")], "events[0].payload.state"),
    ([ev(0, kind="focus", state="blur", colour="red")], "events[0].payload.colour"),
    ([ev(0), ev(0)], "events"),
    ("not a list", "events"),
    ([ev(0, kind="context_query", parent="desk", point=[0, 1], normal=[0, 1, 0])], "events[0].payload.point"),
])
def test_malformed_events_get_field_errors_and_nothing_is_stored(client, app, events, field):
    b = to_trials(client)
    body = json.dumps({"page_id": "p", "events": events}).replace("NaN", "null") if field is None else None
    r = client.post("/api/events", headers={**auth(b), "Content-Type": "application/json"},
                    data=body or json.dumps({"page_id": "p", "events": events}))
    assert r.status_code == 422
    if field is not None:
        assert r.json["field"] == field
    with app.app_context():
        assert db.session.query(Event).count() == 0


def test_bodies_that_are_not_json_objects_and_oversized_bodies(client, app):
    b = to_trials(client)
    r = client.post("/api/events", headers={**auth(b), "Content-Type": "application/json"}, data="[1, 2")
    assert r.status_code == 400 and r.json["field"] == "body"
    huge = {"page_id": "p", "events": [ev(i, kind="search", text="x" * 1900) for i in range(600)]}
    r = client.post("/api/events", headers=auth(b), json=huge)
    assert r.status_code == 413 and r.json["field"] == "body" and "1048576 bytes" in r.json["error"]
    r = client.post("/api/events", headers=auth(b), json={"page_id": "", "events": []})
    assert r.status_code == 422 and r.json["field"] == "page_id"


def editor_scene(app, scene_id: str, which="start") -> dict:
    rt = app.extensions["studies"]["demo"]
    return {"objects": rt.scene(scene_id, which)["objects"]}


def test_suggestions_follow_the_condition_and_every_list_is_logged(client, app):
    b = walk_to(client, app, "none")
    scene = editor_scene(app, b["trial"]["scene"])
    query = {"trial": b["trial"]["index"], "parent": "room", "point": [0.0, 0.0, 0.5], "normal": [0, 1, 0],
             "scene": scene}
    r = client.post("/api/suggest", headers=auth(b), json=query)
    assert r.status_code == 403 and r.json["field"] == "trial"
    other = app.test_client()
    fb = walk_to(other, app, "full", pid="p2")
    query["trial"] = fb["trial"]["index"]
    query["scene"] = editor_scene(app, fb["trial"]["scene"])
    r = other.post("/api/suggest", headers=auth(fb), json=query)
    assert r.status_code == 200, r.json
    data = r.json
    assert data["mode"] == "full" and data["surface_type"] == "up_interior"
    first = data["suggestions"][0]
    assert first["rank"] == 1 and len(first["placement"]) == 16 and first["models"]
    assert first["models"][0]["asset"].startswith("/study/demo/assets/models/")
    assert other.get(first["models"][0]["thumbnail"]).status_code == 200
    with app.app_context():
        logged = db.session.get(ShownList, data["list_id"])
        assert logged.source == "context" and [i["category"] for i in logged.items] == \
            [s["category"] for s in data["suggestions"]]
    stale = dict(query, trial=fb["trial"]["index"] + 1)
    assert other.post("/api/suggest", headers=auth(fb), json=stale).status_code == 409
    bad = dict(query, normal=[0, 0, 0])
    r = other.post("/api/suggest", headers=auth(fb), json=bad)
    assert r.status_code == 400 and r.json["field"] == "normal"
    bad = dict(query, scene={"objects": [{"id": "x"}]})
    r = other.post("/api/suggest", headers=auth(fb), json=bad)
    assert r.status_code == 400 and r.json["field"].startswith("scene")


def test_search_models_and_scenes(client, app):
    b = to_trials(client)
    r = client.get("/api/search?q=desk%20lam", headers=auth(b))
    assert r.status_code == 200 and r.json["hits"][0]["category"] == "DeskLamp"
    with app.app_context():
        logged = db.session.get(ShownList, r.json["list_id"])
        assert logged.source == "search" and logged.query == {"text": "desk lam"}
    assert client.get("/api/search?q=" + "x" * 300, headers=auth(b)).status_code == 400
    assert client.get("/api/search?limit=0", headers=auth(b)).json["field"] == "limit"
    models = client.get("/api/models", headers=auth(b)).json["models"]
    assert len(models) == 118 and models == client.get("/api/models", headers=auth(b)).json["models"]
    target = client.get(f"/api/scenes/{b['trial']['scene']}?which=target", headers=auth(b)).json
    start = client.get(f"/api/scenes/{b['trial']['scene']}?which=start", headers=auth(b)).json
    assert len(start["objects"]) == 1 and len(target["objects"]) > 1
    scene_json.from_dict(target)


def test_a_models_description_is_made_once_and_follows_the_mount_point(client, app):
    """Descriptions come from the study's cache: what one caller changes in its copy is not in the next answer,
    and an app mounted below a path (SCRIPT_NAME) gets its URLs below it, whoever asked first."""
    b = to_trials(client)
    plain = client.get("/api/models", headers=auth(b)).json["models"]
    mounted = client.get("/api/models", headers=auth(b), environ_overrides={"SCRIPT_NAME": "/lab"}).json["models"]
    assert [m["asset"] for m in mounted] == ["/lab" + m["asset"] for m in plain]
    assert all(m["asset"].startswith("/study/demo/") for m in plain)
    rt = app.extensions["studies"]["demo"]
    model = rt.fixed_list[0]
    with app.test_request_context("/"):
        first = rt.describe(model)
        first["asset"], first["name"] = "/elsewhere", "changed"
        assert json.loads(json.dumps(rt.describe(model))) == next(m for m in plain if m["id"] == model.id)
    assert len(rt.model_descriptions) == len(plain)  # one per model, however many mount points asked


def test_trial_done_is_idempotent_and_keeps_the_final_scene(client, app):
    b = to_trials(client)
    final = editor_scene(app, b["trial"]["scene"], "target")
    r = client.post("/api/trial/done", headers=auth(b), json={"trial": -1, "scene": final})
    assert r.status_code == 200 and r.json["trial"]["index"] == 0
    again = client.post("/api/trial/done", headers=auth(b), json={"trial": -1, "scene": final})
    assert again.status_code == 200 and again.json["trial"]["index"] == 0  # a retry moves nothing
    assert client.post("/api/trial/done", headers=auth(b), json={"trial": 5}).status_code == 409
    assert client.post("/api/trial/done", headers=auth(b), json={"trial": "x"}).status_code == 400
    with app.app_context():
        practice = db.session.query(Trial).filter_by(index=-1).one()
        assert len(practice.final_scene["objects"]) == len(final["objects"])


def test_preview_tokens_work_and_write_nothing(app):
    from study_server.base.security import preview_token

    c = app.test_client()
    with app.test_request_context():
        token = preview_token("demo", "full", "bedside")
    h = {"Authorization": f"Bearer {token}"}
    assert c.get("/api/session", headers=h).json["preview"] is True
    assert c.post("/api/events", headers=h, json={"page_id": "x", "events": [ev(0)]}).json == {
        "acked_seq": 0, "stored": False}
    scene = editor_scene(app, "bedside")
    r = c.post("/api/suggest", headers=h, json={"trial": 0, "parent": "room", "point": [0, 0, 0.5],
                                                "normal": [0, 1, 0], "scene": scene})
    assert r.status_code == 200 and r.json["suggestions"]
    assert c.get("/api/session", headers={"Authorization": "Bearer preview.forged"}).status_code == 401
    with app.app_context():
        assert db.session.query(Event).count() == 0 and db.session.query(ShownList).count() == 0


def test_openapi_and_event_schema_are_served(client):
    doc = client.get("/api/openapi.json").json
    assert doc["openapi"].startswith("3.1") and "/api/events" in doc["paths"]
    schema = client.get("/api/events/schema.json").json
    assert "insert" in schema["properties"]["type"]["enum"]


def test_security_headers(client):
    r = client.get("/study/demo/start?pid=h")
    csp = r.headers["Content-Security-Policy"]
    assert "script-src 'self'" in csp and "frame-ancestors 'self'" in csp
    assert r.headers["X-Content-Type-Options"] == "nosniff"


def test_unknown_urls_and_methods(client):
    r = client.get("/api/nothing-here")
    assert r.status_code == 404 and r.json["error"]
    assert client.get("/api/events").status_code == 405
    page = client.get("/study/demo/no-such-page")
    assert page.status_code == 404 and b"use the link you were given" in page.data
    assert client.get("/study/nope/").status_code == 404


def test_numbers_too_large_for_a_float_are_named_not_a_server_error(client, app):
    """JSON integers have no bound; a client that sends 10**400 where a number belongs gets a 4xx naming it."""
    b = to_trials(client)
    huge = 10**400
    target = editor_scene(app, b["trial"]["scene"], "target")
    state = next(o for o in target["objects"] if o["parent"] is not None)
    move = {"seq": 0, "t": 1.0, "type": "move_end", "trial": -1, "payload": {
        "object": state["id"], "distance": 0.1, "objects": [dict(state, transform=[huge] + state["transform"][1:])]}}
    for body, field in (
            ({"page_id": "p", "vocabulary": 2, "events": [dict(move, payload={"object": "x", "distance": 0.1,
                                                                          "objects": []}, t=huge)]}, "events[0].t"),
            ({"page_id": "p", "vocabulary": 2, "events": [move]}, "events[0].payload.objects[0].transform"),
            ({"page_id": "p", "vocabulary": 2.0, "events": []}, "vocabulary"),
            ({"page_id": "p", "vocabulary": 2, "events": [
                {"seq": 0, "t": 1.0, "type": "insert", "trial": -1, "payload": {
                    "object": state["id"], "model": state["model_id"], "category": state["category"], "rank": huge,
                    "source": "context", "objects": [state]}}]}, "events[0].payload.rank")):
        r = client.post("/api/events", headers=auth(b), json=body)
        assert r.status_code == 422 and r.json["field"] == field, r.json
    scene = {"objects": [dict(o, transform=[huge] + o["transform"][1:]) if o is state else o
                         for o in target["objects"]]}
    r = client.post("/api/trial/done", headers=auth(b), json={"trial": -1, "scene": scene})
    assert r.status_code == 400 and r.json["field"] == "scene.transform", r.json
    query = {"trial": -1, "parent": "room", "point": [huge, 0.0, 0.5], "normal": [0.0, 1.0, 0.0],
             "scene": editor_scene(app, b["trial"]["scene"])}
    r = client.post("/api/suggest", headers=auth(b), json=query)
    assert r.status_code in (400, 422) and r.json["field"] == "point", r.json
    for trial, last_seq in ((huge, None), (2**64, None), (-1, huge), (-1, 1.5), (-1, True)):
        r = client.post("/api/trial/done", headers=auth(b), json={"trial": trial, "last_seq": last_seq} | (
            {} if last_seq is not None else {"last_seq": None}))
        assert r.status_code == 400, (trial, last_seq, r.json)
    with app.app_context():
        assert db.session.query(Event).count() == 0 and db.session.query(Trial).filter(
            Trial.done_at.isnot(None)).count() == 0
