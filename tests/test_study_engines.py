"""Engines in a study: a condition that names its engine — validated with the file, line and key of a mistake,
served (the learned engine, an http engine that misbehaves, an open circuit), recorded in the export's manifest and
in /healthz and the admin's dashboard; the published engine schemas in the server's OpenAPI document; the workers'
shared wait slots."""

from __future__ import annotations

import hashlib
import json
import os
import subprocess
import sys
import time
from pathlib import Path

import pytest
from demostudy import copy_demo_study, make_app
from enginehelp import a_query, http_engine
from flowhelp import auth, csrf, to_trials

from scenesuggest import engines
from scenesuggest.engines.protocol import LoadContext
from scenesuggest.errors import SceneSuggestError


def study_with_engine(tmp_path: Path, engine: str) -> Path:
    """A copy of the demo study whose ``full`` condition names ``engine`` (a TOML inline table)."""
    path = copy_demo_study(tmp_path)
    path.write_text(path.read_text().replace('engine = { orientation = "learned" }', f"engine = {engine}", 1))
    return path


def learned_study(tmp_path: Path, learned: Path) -> Path:
    return study_with_engine(tmp_path, f'{{ name = "learned", file = "{learned}" }}')


def http_study(tmp_path: Path, url: str) -> Path:
    return study_with_engine(tmp_path, f'{{ name = "http", url = "{url}", timeout_ms = 300 }}')


def test_a_condition_served_by_the_learned_engine(tmp_path, learned_file, demo_resources):
    from study_server.experimenter.export import export_files

    app = make_app(tmp_path, studies=[learned_study(tmp_path, learned_file)])
    client = app.test_client()
    b = to_trials(client)  # the practice trial: the 'full' condition
    start = app.extensions["studies"]["demo"].scene(b["trial"]["scene"], "start")
    r = client.post("/api/suggest", headers=auth(b), json={"trial": b["trial"]["index"], "parent": "room",
                                                           "scene": {"objects": start["objects"]},
                                                           "point": [0.0, 0.0, 0.5], "normal": [0, 1, 0]})
    assert r.status_code == 200 and r.json["engine"] == "learned" and r.json["suggestions"], r.json
    assert all(s["models"] for s in r.json["suggestions"])
    health = client.get("/healthz").json  # by engine, not by condition; nothing loaded by asking
    assert health["ok"] and health["engines"]["demo"] == {"paper": {"version": "1", "status": "not loaded yet"},
                                                          "learned": {"version": "1", "status": "ok"}}
    with app.app_context():
        manifest = json.loads(export_files(app.extensions["studies"]["demo"])["manifest.json"])
    assert manifest["engines"]["full"] == {"engine": "learned", "version": "1", "options": {"file": str(learned_file)},
                                           "file_sha256": hashlib.sha256(learned_file.read_bytes()).hexdigest()}
    assert manifest["engines"]["basic"]["engine"] == "paper"
    assert manifest["engines"]["basic"]["file_sha256"] == manifest["resources"]["priors_sha256"]


def test_a_missing_learned_file_stops_the_server_naming_the_condition(tmp_path, demo_resources):
    from study_server.studies.prepare import prepare
    from study_server.studies.served import load_studies
    from study_server.studies.study_file import load_study

    path = learned_study(tmp_path, tmp_path / "nowhere.npz")
    assert prepare(load_study(path), lambda items, label="": items, print) == []  # a file it names is not built
    assert not (tmp_path / "nowhere.npz").exists()
    with pytest.raises(SceneSuggestError) as info:
        load_studies([path])
    assert info.value.field == "conditions[2].engine" and "scenesuggest engine train learned" in info.value.message


def test_a_damaged_engine_file_is_a_503_without_its_path_and_healthz_says_so(tmp_path, learned_file,
                                                                             demo_resources):
    import shutil

    damaged = tmp_path / "damaged.learned.npz"
    shutil.copy(learned_file, damaged)
    app = make_app(tmp_path, studies=[learned_study(tmp_path, damaged)])
    import zipfile

    with zipfile.ZipFile(learned_file) as src, zipfile.ZipFile(damaged, "w") as dst:
        for item in src.infolist():  # every entry but the ranker: the metadata still reads
            if item.filename != "ranker.npy":
                dst.writestr(item, src.read(item.filename))
    client = app.test_client()
    b = to_trials(client)
    start = app.extensions["studies"]["demo"].scene(b["trial"]["scene"], "start")
    r = client.post("/api/suggest", headers=auth(b), json={"trial": b["trial"]["index"], "parent": "room",
                                                           "scene": {"objects": start["objects"]},
                                                           "point": [0.0, 0.0, 0.5], "normal": [0, 1, 0]})
    assert r.status_code == 503 and r.json["field"] == "engine" and str(tmp_path) not in r.get_data(as_text=True)
    health = client.get("/healthz")
    assert health.status_code == 503 and health.json["engines"]["demo"]["learned"]["status"] == \
        "unavailable (SceneSuggestError)" and str(tmp_path) not in health.get_data(as_text=True)


@pytest.mark.parametrize(("engine", "key", "words"), [
    ('{ name = "psychic" }', "conditions[2].engine.name", "unknown engine 'psychic': one of paper, learned"),
    ('{ name = "learned", lambda2 = 1 }', "conditions[2].engine.lambda2", "unknown key: this engine takes name, file"),
    ('{ name = "http", url = "ftp://x" }', "conditions[2].engine.url", "http:// or https://"),
    ('{ name = "frequency", orientation = "sideways" }', "conditions[2].engine.orientation", "one of learned, paper"),
])
def test_a_study_files_engine_mistakes_name_file_line_and_key(tmp_path, engine, key, words):
    path = study_with_engine(tmp_path, engine)
    line = next(n for n, t in enumerate(path.read_text().splitlines(), start=1) if t.startswith("engine = "))
    proc = subprocess.run([sys.executable, "-m", "scenesuggest.cli", "study", "validate", str(path)],
                          capture_output=True, text=True)
    assert proc.returncode == 2 and f"{path}:{line}: field '{key}': " in proc.stderr and words in proc.stderr, \
        proc.stderr
    assert "Traceback" not in proc.stderr


def test_a_condition_served_by_a_hostile_engine_still_suggests_and_logs_why(tmp_path, external, demo_resources):
    from sqlalchemy import select
    from werkzeug.security import generate_password_hash

    from study_server.base.extensions import db
    from study_server.base.models import SessionLog, ShownList

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


def test_an_open_circuit_answers_participants_at_once_and_the_admin_sees_it(tmp_path, external, demo_resources):
    from sqlalchemy import select
    from werkzeug.security import generate_password_hash

    from study_server.base.extensions import db
    from study_server.base.models import SessionLog

    app = make_app(tmp_path, studies=[http_study(tmp_path, f"{external}/hang")],
                   ADMIN_PASSWORD_HASH=generate_password_hash("admin-password"))
    client = app.test_client()
    b = to_trials(client)
    start = app.extensions["studies"]["demo"].scene(b["trial"]["scene"], "start")
    body = {"trial": b["trial"]["index"], "scene": {"objects": start["objects"]}, "parent": "room",
            "point": [0.0, 0.0, 0.5], "normal": [0, 1, 0]}
    took = []
    for _ in range(5):
        started = time.monotonic()
        r = client.post("/api/suggest", headers=auth(b), json=body)
        took.append(time.monotonic() - started)
        assert r.status_code == 200 and r.json["engine"] == "paper"
    assert min(took[:3]) >= 0.29 and max(took[3:]) < 0.25, took  # the circuit opened after three timeouts
    with app.app_context():
        rows = db.session.scalars(select(SessionLog).where(SessionLog.kind == "engine_circuit")).all()
        assert [(r.study_id, r.detail["condition"], r.detail["state"], r.detail["failures"]) for r in rows] == [
            ("demo", "full", "open", 3)]
    admin = app.test_client()
    page = admin.get("/admin/login")
    admin.post("/admin/login", data={"csrf_token": csrf(page), "password": "admin-password"})
    dashboard = admin.get("/admin/").get_data(as_text=True)
    assert "after 3 failures (no answer within 300 ms): asked again every 10.0 s or more" in dashboard


def test_the_reference_engine_server_and_the_http_engine_keep_the_published_schemas(demo_priors, tmp_path):
    """`scenesuggest engine serve` in its own process answers the http engine; the query sent and the answer
    given validate against the schemas the API's OpenAPI document publishes, and the answer is the served
    engine's own."""
    import socket
    import urllib.request

    import jsonschema
    import orjson

    from study_server.base.openapi import openapi_document

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


def test_served_workers_share_one_folder_of_wait_slots(tmp_path, monkeypatch):
    """gunicorn's on_starting (study_server.base.gunicorn_settings) gives the workers a folder and their number; an app
    then bounds its http engines' waits to half of them."""
    from study_server.base import gunicorn_settings
    from study_server.studies.served import engine_wait_slots

    monkeypatch.delenv(gunicorn_settings.WAITS, raising=False)
    assert engine_wait_slots() is None  # one process: no bound

    class Server:
        class cfg:
            workers = 5

    monkeypatch.setenv(gunicorn_settings.WAITS, "")  # restored after the test, as is the next
    monkeypatch.setenv(gunicorn_settings.WORKERS, "1")
    gunicorn_settings.on_starting(Server)
    try:
        slots = engine_wait_slots()
        assert slots.count == 2 and slots.folder == Path(os.environ[gunicorn_settings.WAITS])
    finally:
        gunicorn_settings.on_exit(Server)
    assert not slots.folder.exists()
