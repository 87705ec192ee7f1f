"""Every endpoint of the OpenAPI document, fuzzed: arbitrary and near-valid JSON never gets a 500, and a
rejected request writes nothing."""

import json

import pytest
from flowhelp import auth, to_trials
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from study_server.base.extensions import db
from study_server.base.models import Event, ShownList, SurveyResponse, Trial

JSON = st.recursive(
    st.none() | st.booleans() | st.integers(-2**40, 2**40) | st.sampled_from([2**64, -10**400, 10**400])
    | st.floats(allow_nan=False) | st.text(max_size=30),
    lambda inner: st.lists(inner, max_size=5) | st.dictionaries(st.text(max_size=10), inner, max_size=5),
    max_leaves=20)
# what a client can put in a URL path segment and in a header at all (the test client refuses the rest)
URL_SAFE = st.characters(min_codepoint=33, max_codepoint=0x2FFF, blacklist_characters="?#/%\\",
                         blacklist_categories=("Cs",))
HEADER_SAFE = st.characters(min_codepoint=32, max_codepoint=126)
EVENT_TYPES = ["insert", "focus", "move_end", "rotate_end", "context_query", "search", "teleport", ""]


def near_valid_event():
    return st.fixed_dictionaries({
        "seq": st.one_of(st.integers(-3, 3000), st.text(max_size=3), st.none(), st.just(10**400)),
        "t": st.one_of(st.floats(allow_nan=True, allow_infinity=True), st.text(max_size=3), st.just(10**400)),
        "type": st.sampled_from(EVENT_TYPES),
        "trial": st.one_of(st.none(), st.integers(-5, 20), st.booleans()),
        "payload": st.dictionaries(st.sampled_from(["object", "model", "rank", "source", "state", "point",
                                                    "distance", "angle", "category", "x"]), JSON, max_size=6)})


def counts(app):
    with app.app_context():
        return tuple(db.session.query(m).count() for m in (Event, ShownList, SurveyResponse))


@pytest.fixture(scope="module")
def fuzz_app(tmp_path_factory, demo_resources):
    from demostudy import make_app

    app = make_app(tmp_path_factory.mktemp("fuzz"))
    c = app.test_client()
    b = to_trials(c)
    return app, c, b


FUZZ = settings(max_examples=120, deadline=None, suppress_health_check=list(HealthCheck))


@FUZZ
@given(body=st.one_of(JSON, st.fixed_dictionaries({"page_id": st.one_of(st.text(max_size=70), JSON),
                                                   "events": st.one_of(JSON, st.lists(near_valid_event(),
                                                                                      max_size=4))})))
def test_fuzz_events(fuzz_app, body):
    app, c, b = fuzz_app
    before = counts(app)
    r = c.post("/api/events", headers={**auth(b), "Content-Type": "application/json"}, data=json.dumps(body))
    assert r.status_code < 500, r.json
    if r.status_code >= 400:
        assert counts(app) == before and r.json["error"]


@FUZZ
@given(body=st.one_of(JSON, st.fixed_dictionaries({
    "trial": st.one_of(st.just(-1), JSON), "parent": st.one_of(st.just("room"), JSON),
    "point": st.one_of(st.lists(st.floats(), min_size=3, max_size=3), JSON),
    "normal": st.one_of(st.lists(st.floats(), min_size=3, max_size=3), JSON),
    "scene": st.one_of(JSON, st.fixed_dictionaries({"objects": st.lists(st.dictionaries(
        st.sampled_from(["id", "model_id", "category", "size", "transform", "parent"]), JSON), max_size=3)}))})))
def test_fuzz_suggest(fuzz_app, body):
    app, c, b = fuzz_app
    before = counts(app)
    r = c.post("/api/suggest", headers={**auth(b), "Content-Type": "application/json"}, data=json.dumps(body))
    assert r.status_code < 500, r.json
    if r.status_code >= 400:
        assert counts(app) == before


@FUZZ
@given(body=st.one_of(JSON, st.fixed_dictionaries({"trial": JSON, "scene": JSON, "last_seq": JSON})))
def test_fuzz_trial_done(fuzz_app, body):
    app, c, b = fuzz_app
    with app.app_context():
        done_before = db.session.query(Trial).filter(Trial.done_at.is_not(None)).count()
    r = c.post("/api/trial/done", headers={**auth(b), "Content-Type": "application/json"}, data=json.dumps(body))
    assert r.status_code < 500, r.json
    if r.status_code >= 400:
        with app.app_context():
            assert db.session.query(Trial).filter(Trial.done_at.is_not(None)).count() == done_before


@FUZZ
@given(q=st.text(max_size=250), limit=st.one_of(st.text(max_size=5), st.integers(-5, 500).map(str)),
       scene=st.text(URL_SAFE, min_size=1, max_size=40), which=st.text(max_size=8),
       token=st.one_of(st.text(HEADER_SAFE, max_size=80), st.just("preview.x")))
def test_fuzz_get_endpoints_and_tokens(fuzz_app, q, limit, scene, which, token):
    app, c, b = fuzz_app
    for path, params in (("/api/search", {"q": q, "limit": limit}), (f"/api/scenes/{scene}", {"which": which}),
                         ("/api/session", {}), ("/api/models", {})):
        r = c.get(path, query_string=params, headers=auth(b))
        assert r.status_code < 500
        forged = c.get(path, query_string=params, headers={"Authorization": f"Bearer {token}"})
        assert forged.status_code in (401, 404)
    assert c.post("/api/heartbeat", headers={"Authorization": f"Bearer {token}"}).status_code == 401
    assert c.post("/api/heartbeat", headers=auth(b)).status_code == 200


#: The API paths the fuzzers above send requests to.
FUZZED = {"/api/events", "/api/suggest", "/api/trial/done", "/api/search", "/api/scenes/{scene_id}", "/api/session",
          "/api/models", "/api/heartbeat", "/api/events/schema.json", "/api/openapi.json"}


def test_every_route_of_the_api_is_documented_and_fuzzed(app):
    import re

    from study_server.base.openapi import openapi_document

    routes = {re.sub(r"<(?:\w+:)?(\w+)>", r"{\1}", rule.rule) for rule in app.url_map.iter_rules()
              if rule.rule.startswith("/api/")}
    assert routes == set(openapi_document()["paths"])  # every route the app serves is in the OpenAPI document
    assert routes <= FUZZED, routes - FUZZED  # … and the fuzzers reach it
