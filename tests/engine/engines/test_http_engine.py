"""The http engine: a real external engine in its own process — a good one and hostile ones (slow, garbage, a
100 MB body, a connection that never closes, a status line dribbled out) — answered strictly, and whatever it
does, the participant gets a list within the timeout (the fallback's, with the reason logged)."""

from __future__ import annotations

import subprocess
import sys
import time
from pathlib import Path

import pytest
from conftest import DEMO_STUDY, make_app
from flowhelp import auth, csrf, to_trials

from scenesuggest import engines
from scenesuggest.engines.http import HttpEngine, parse_answer
from scenesuggest.engines.protocol import LoadContext
from scenesuggest.errors import SceneSuggestError
from scenesuggest.scenes import scene_json
from scenesuggest.suggestion.query import ContextQuery

HERE = Path(__file__).resolve().parents[2]  # tests/, where the external engine lives


@pytest.fixture(scope="module")
def external(tmp_path_factory):
    """The external engine of tests/external_engine.py in its own process; yields its base URL."""
    port_file = tmp_path_factory.mktemp("engine") / "port"
    proc = subprocess.Popen([sys.executable, str(HERE / "external_engine.py"), str(port_file)])
    try:
        deadline = time.monotonic() + 10
        while not port_file.exists() or not port_file.read_text():
            assert proc.poll() is None and time.monotonic() < deadline, "the external engine did not start"
            time.sleep(0.02)
        yield f"http://127.0.0.1:{port_file.read_text()}"
    finally:
        proc.kill()
        proc.wait()


@pytest.fixture(scope="module")
def demo_priors(demo_resources):
    from study_server.study_file import load_study

    return load_study(DEMO_STUDY).priors


def http_engine(url: str, priors: Path, **options) -> HttpEngine:
    spec = engines.configure({"name": "http", "url": url, **options})
    return engines.load(spec, LoadContext(priors))


def a_query() -> ContextQuery:
    """A click where a target object of the demo's desk corner stands (the object removed)."""
    scene = scene_json.load(DEMO_STUDY.parent / "scenes" / "desk-corner.json")
    o = next(o for o in scene if o.parent is not None and o.contact_point is not None)
    return ContextQuery(scene.without(o.id), o.parent, o.contact_point, o.contact_normal)


def test_a_good_external_engine_answers(external, demo_priors):
    engine = http_engine(f"{external}/good", demo_priors)
    query = a_query()
    found = engine.suggest(query, "full", top=5)
    allowed = sorted(engine.categories, reverse=True)
    assert found.engine == "http" and found.fallback is None
    assert [s.category for s in found] == allowed[:5]  # what the external engine said, in its order
    assert found[0].terms == {"external": 1.0} and found[0].heading_deg == pytest.approx(90.0, abs=1e-6)
    assert found[0].attachment_face == "bottom" and found[0].models == engine.categories[allowed[0]]
    only = set(allowed[-3:])
    assert {s.category for s in engine.suggest(query, "basic", only=only)} == only  # the query names what it allows


@pytest.mark.parametrize(("path", "reason", "within_s"), [
    ("slow", "no answer within 300 ms", 1.0),
    ("hang", "no answer within 300 ms", 1.0),
    ("drip", "no answer within 300 ms", 1.0),
    ("huge", "answer larger than 1048576 bytes", 1.0),
    ("garbage", "invalid answer: not JSON", 1.0),
    ("nan", "invalid answer: not JSON", 1.0),  # NaN (or 1e999) is not JSON: nothing non-finite gets through
    ("unknown", "suggestions[0].category is not one the query allows", 1.0),
    ("scaled", "suggestions[0].placement is not a rigid transform", 1.0),
    ("many", "5000 suggestions, at most 40", 1.0),
    ("error", "HTTP 500", 1.0),
    ("stream", "answer larger than 1048576 bytes", 1.0),
    ("upside", "suggestions[0].attachment_face is not the face its placement turns to the clicked surface", 1.0),
])
def test_a_hostile_engine_gives_the_fallbacks_list_within_the_timeout(external, demo_priors, path, reason,
                                                                     within_s):
    engine = http_engine(f"{external}/{path}", demo_priors)
    paper = engines.load(engines.configure({}), LoadContext(demo_priors))
    query = a_query()
    started = time.monotonic()
    found = engine.suggest(query, "full", top=10)
    assert time.monotonic() - started < within_s
    assert found.fallback is not None and reason in found.fallback and "127.0.0.1" not in found.fallback
    assert found.engine == "paper"
    assert [s.category for s in found] == [s.category for s in paper.suggest(query, "full", top=10)]
    assert engine.fallbacks == 1 and engine.last_server_ms() is None


def test_the_same_engine_answers_again_after_a_failure(external, demo_priors):
    engine = http_engine(f"{external}/flaky?k=recovery", demo_priors)
    answers = [engine.suggest(a_query(), "full", top=3) for _ in range(4)]
    assert [a.fallback for a in answers] == ["HTTP 500", None, "HTTP 500", None]
    assert [a.engine for a in answers] == ["paper", "http", "paper", "http"]


def test_a_connection_the_engine_closed_while_idle_is_not_a_failure(external, demo_priors):
    """Servers close kept-alive connections after a few idle seconds; participants click less often than that."""
    engine = http_engine(f"{external}/idle-close", demo_priors)
    for _ in range(3):
        assert engine.suggest(a_query(), "full", top=3).fallback is None
        time.sleep(0.4)  # the engine has closed the connection meanwhile


def test_a_tls_engine_that_never_shakes_hands_is_timed_out(demo_priors):
    import socket

    with socket.socket() as listening:  # the kernel accepts the connection; nobody ever answers the handshake
        listening.bind(("127.0.0.1", 0))
        listening.listen(8)
        engine = http_engine(f"https://127.0.0.1:{listening.getsockname()[1]}/", demo_priors)
        started = time.monotonic()
        found = engine.suggest(a_query(), "full", top=3)
        assert time.monotonic() - started < 1.0 and found.fallback == "no answer within 300 ms"


def test_no_engine_listening_is_a_fallback_too(demo_priors):
    import socket

    with socket.socket() as s:  # a port nobody listens on
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    found = http_engine(f"http://127.0.0.1:{port}/", demo_priors).suggest(a_query(), "basic", top=3)
    assert found.fallback.startswith("connection failed") and len(found) == 3


def test_connections_are_kept_alive(external, demo_priors):
    import json
    import urllib.request

    def connections() -> int:
        with urllib.request.urlopen(f"{external}/count", data=b"{}") as r:
            return json.loads(r.read())["connections"]

    engine = http_engine(f"{external}/good", demo_priors)
    before = connections()
    for _ in range(20):
        assert engine.suggest(a_query(), "full", top=3).fallback is None
    assert connections() - before == 2  # one for the engine's twenty queries, one for the count itself


def test_a_bad_query_is_still_the_participants_error(external, demo_priors):
    engine = http_engine(f"{external}/good", demo_priors)
    query = a_query()
    with pytest.raises(SceneSuggestError) as info:
        engine.suggest(ContextQuery(query.scene, "nobody", query.point, query.normal), "full")
    assert info.value.field == "parent"


def test_answers_are_checked_strictly():
    from scenesuggest.engines.http import EngineUnavailable

    point, normal = (1.0, 0.75, 2.0), (0.0, 1.0, 0.0)
    upright = [1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 1.0, 0.75, 2.0, 1]
    models = {"Mug": ("m1", "m2"), "Lamp": ("l1",)}

    def problem(doc) -> str:
        from scenesuggest.engines.http import EngineUnavailable

        with pytest.raises(EngineUnavailable) as info:
            parse_answer(doc, {"Mug", "Lamp"}, models, point, normal, 3)
        return str(info.value)

    ok = parse_answer({"suggestions": [{"category": "Mug", "score": 2, "placement": upright, "models": ["m2"]}]},
                      {"Mug", "Lamp"}, models, point, normal, 3)
    assert ok[0].models == ("m2",) and ok[0].attachment_face == "bottom" and ok[0].rank == 1
    item = {"category": "Mug", "score": 1, "placement": upright}
    assert "expected" in problem([item])
    assert "appears twice" in problem({"suggestions": [item, item]})
    assert "4 suggestions, at most 3" in problem({"suggestions": [item] * 4})
    # a placeholder is refused even where the query would allow it (a library that named a model "Unknown")
    with pytest.raises(EngineUnavailable, match=r"suggestions\[0\].category 'Unknown' is a placeholder"):
        parse_answer({"suggestions": [{**item, "category": "Unknown"}]}, {"Unknown", "Mug"},
                     {**models, "Unknown": ("u1",)}, point, normal, 3)
    assert "score" in problem({"suggestions": [{**item, "score": True}]})
    assert "16 finite numbers" in problem({"suggestions": [{**item, "placement": upright[:15]}]})
    assert "16 finite numbers" in problem({"suggestions": [{**item, "placement": [*upright[:15], "1"]}]})
    mirrored = [-1, 0, 0, 0, *upright[4:]]
    assert "rigid" in problem({"suggestions": [{**item, "placement": mirrored}]})
    far = [*upright[:12], 500.0, 0.75, 2.0, 1]
    assert "100 m" in problem({"suggestions": [{**item, "placement": far}]})
    assert "models" in problem({"suggestions": [{**item, "models": ["l1"]}]})
    assert "attachment_face" in problem({"suggestions": [{**item, "attachment_face": "side"}]})
    assert "terms" in problem({"suggestions": [{**item, "terms": {"x": "big"}}]})
    assert "heading_deg" in problem({"suggestions": [{**item, "heading_deg": float("inf")}]})


@pytest.mark.parametrize(("table", "key", "words"), [
    ({"name": "http"}, "url", "missing"),
    ({"name": "http", "url": "ftp://x.org/"}, "url", "http:// or https://"),
    ({"name": "http", "url": "https://user:pw@x.org/"}, "url", "no credentials"),
    ({"name": "http", "url": "http://x.org:99999/"}, "url", "port"),
    ({"name": "http", "url": "http://x.org/", "timeout_ms": 0}, "timeout_ms", "from 1 to 2000"),
    ({"name": "http", "url": "http://x.org/a b"}, "url", "without spaces or control characters"),
    ({"name": "http", "url": "http://x.org/", "timeout_ms": 1.5}, "timeout_ms", "integer"),
    ({"name": "http", "url": "http://x.org/", "fallback": "http"}, "fallback", "other than http"),
    ({"name": "http", "url": "http://x.org/", "fallback": "psychic"}, "fallback.name", "unknown engine"),
    ({"name": "http", "url": "http://x.org/", "fallback": {"name": "paper", "lambda2": -1}}, "fallback.lambda2", "≥ 0"),
    ({"name": "http", "url": "http://x.org/", "retries": 3}, "retries", "unknown key"),
    ({"name": "psychic"}, "name", "unknown engine 'psychic'"),
    ({"name": 5}, "name", "expected the name of an engine"),
    ({"name": "learned", "file": ""}, "file", "path"),
    ({"name": "frequency", "lambda1": 2}, "lambda1", "unknown key"),
])
def test_engine_tables_are_validated_naming_the_key(table, key, words):
    with pytest.raises(SceneSuggestError) as info:
        engines.configure(table)
    assert info.value.field == key and words in info.value.message


# --- through the study server ---------------------------------------------------------------------------------
def http_study(tmp_path: Path, url: str) -> Path:
    import shutil

    folder = tmp_path / "demo"
    shutil.copytree(DEMO_STUDY.parent, folder)
    path = folder / "study.toml"
    text = path.read_text()
    path.write_text(text.replace('engine = { orientation = "learned" }',
                                 f'engine = {{ name = "http", url = "{url}", timeout_ms = 300 }}', 1))
    return path


def test_a_condition_served_by_a_hostile_engine_still_suggests_and_logs_why(tmp_path, external, demo_resources):
    from sqlalchemy import select
    from werkzeug.security import generate_password_hash

    from study_server.extensions import db
    from study_server.models import SessionLog, ShownList

    app = make_app(tmp_path, studies=[http_study(tmp_path, f"{external}/slow")],
                   ADMIN_PASSWORD_HASH=generate_password_hash("admin-password"))
    client = app.test_client()
    b = to_trials(client)  # the practice trial, in the 'full' condition that the external engine serves
    assert b["trial"]["condition"] == "full"
    start = app.extensions["studies"]["demo"].scene(b["trial"]["scene"], "start")
    body = {"trial": b["trial"]["index"], "scene": {"objects": start["objects"]}, "parent": "room",
            "point": [0.0, 0.0, 0.5], "normal": [0, 1, 0]}
    started = time.monotonic()
    r = client.post("/api/suggest", headers=auth(b), json=body)
    assert r.status_code == 200 and r.json["suggestions"] and time.monotonic() - started < 1.5
    assert r.json["engine"] == "paper"  # the fallback's list
    with app.app_context():
        logged = db.session.scalars(select(SessionLog).where(SessionLog.kind == "engine_fallback")).all()
        assert len(logged) == 1 and logged[0].detail["reason"] == "no answer within 300 ms"
        assert logged[0].detail["condition"] == "full" and logged[0].detail["engine"] == "http"
        shown = db.session.get(ShownList, r.json["list_id"])
        assert shown.query["engine"] == "paper" and shown.query["fallback"] == "no answer within 300 ms"
    health = client.get("/healthz").json
    assert health["engines"]["demo"]["http"] == {"version": "1", "status": "ok", "fallbacks": 1}
    assert external not in client.get("/healthz").get_data(as_text=True)  # no URL in the public answer
    admin = app.test_client()
    page = admin.get("/admin/login")
    admin.post("/admin/login", data={"csrf_token": csrf(page), "password": "admin-password"})
    dashboard = admin.get("/admin/").get_data(as_text=True)
    table = dashboard[dashboard.index('<table id="engines">'):]
    table = table[:table.index("</table>")]
    assert "<td>full</td><td>http" in table and "falls back to paper" in table
    assert "<td>1</td><td>no answer within 300 ms (1)</td>" in table and external not in table


def test_the_reference_engine_server_and_the_http_engine_keep_the_published_schemas(demo_priors, tmp_path):
    """`scenesuggest engine serve` in its own process answers the http engine; the query sent and the answer
    given validate against the schemas the API's OpenAPI document publishes, and the answer is the served
    engine's own."""
    import socket
    import urllib.request

    import jsonschema
    import orjson

    from study_server.openapi import openapi_document

    schemas = openapi_document()["components"]["schemas"]
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    server = subprocess.Popen([sys.executable, "-m", "scenesuggest.cli", "engine", "serve", "paper", "--priors",
                               str(demo_priors), "--port", str(port)], stderr=subprocess.PIPE, text=True)
    try:
        assert "serving the paper engine" in server.stderr.readline()
        engine = http_engine(f"http://127.0.0.1:{port}/", demo_priors)
        sent: list[bytes] = []
        exchange = engine._exchange
        engine._exchange = lambda body: (sent.append(body), exchange(body))[1]
        query = a_query()
        found = engine.suggest(query, "full", top=8)
        assert found.engine == "http" and found.fallback is None and engine.last_server_ms() > 0
        local = engines.load(engines.configure({}), LoadContext(demo_priors)).suggest(query, "full", top=8)
        assert [s.category for s in found] == [s.category for s in local]
        jsonschema.validate(orjson.loads(sent[0]), schemas["EngineQuery"])
        request = urllib.request.Request(f"http://127.0.0.1:{port}/", data=sent[0], method="POST")
        with urllib.request.urlopen(request) as r:
            jsonschema.validate(orjson.loads(r.read()), schemas["EngineAnswer"])
        import http.client

        for length, status in (("999999999", 413), ("²", 411)):
            conn = http.client.HTTPConnection("127.0.0.1", port, timeout=5)
            conn.putrequest("POST", "/")
            conn.putheader("Content-Length", length.encode("latin-1"))
            conn.endheaders()
            answer = conn.getresponse()
            assert answer.status == status and b"Content-Length of at most" in answer.read()
            conn.close()
        for body, words in ((b"[1,", "not JSON"), (b'{"mode": "sideways"}', "expected one of basic, full")):
            request = urllib.request.Request(f"http://127.0.0.1:{port}/", data=body, method="POST")
            with pytest.raises(urllib.error.HTTPError) as info:
                urllib.request.urlopen(request)
            assert info.value.code == 400 and words in info.value.read().decode()
    finally:
        server.kill()
        server.wait()
