"""Attacks on the study server: path traversal, hostile JSON, SQL-looking input, embedding, production settings."""

from __future__ import annotations

import json
import sqlite3

import pytest
from demostudy import make_app
from flowhelp import auth, boot, enter, to_trials

from study_server import create_app
from study_server.base.config import ConfigError


@pytest.mark.parametrize("path", [
    "/study/demo/assets/../../../../etc/passwd",
    "/study/demo/assets/models/../../../../etc/passwd",
    "/study/demo/assets/models/%2e%2e/%2e%2e/%2e%2e/etc/passwd",
    "/study/demo/assets/models/..%2f..%2f..%2fstudy.toml",
    "/study/demo/assets//etc/passwd",
    "/study/demo/assets/models/%00.glb",
    "/vendor/three/build/../../../../pyproject.toml",
    "/vendor/three/build/%2e%2e/%2e%2e/package.json",
    "/vendor/three/examples/jsm/../../../../../etc/passwd.js",
])
def test_asset_routes_do_not_leave_their_folders(client, path):
    r = client.get(path, follow_redirects=True)  # Werkzeug merges double slashes with a redirect
    assert r.status_code in (400, 404), (path, r.status_code)
    assert b"root:" not in r.data and b"[project]" not in r.data and b"[study]" not in r.data


def test_deeply_nested_json_gets_a_400_not_a_crash(client, app):
    b = to_trials(client)
    nested = "[" * 100_000 + "]" * 100_000
    for path in ("/api/events", "/api/suggest", "/api/trial/done"):
        r = client.post(path, data=nested, headers={**auth(b), "Content-Type": "application/json"})
        assert r.status_code == 400, (path, r.status_code)
        assert r.json["field"] == "body"
    deep_payload = {"page_id": b["page_id"], "events": [{"seq": 0, "t": 1.0, "type": "search", "trial": 0,
                                                          "payload": {"text": json.loads("[" * 50 + "]" * 50)}}]}
    r = client.post("/api/events", json=deep_payload, headers=auth(b))
    assert r.status_code == 422 and r.json["field"] == "events[0].payload.text"


SQLISH = ["'; DROP TABLE events; --", "\" OR 1=1 --", "sofa') UNION SELECT token FROM participants --"]


def test_sql_looking_input_is_data(client, app):
    b = to_trials(client)
    for i, text in enumerate(SQLISH):
        r = client.get("/api/search", query_string={"q": text}, headers=auth(b))
        assert r.status_code == 200 and r.json["query"] == text
        event = {"seq": i, "t": 1.0 + i, "type": "search", "trial": b["trial"]["index"], "payload": {"text": text}}
        assert client.post("/api/events", json={"page_id": b["page_id"], "events": [event]},
                           headers=auth(b)).status_code == 200
    r = client.get("/study/demo/start?pid=" + SQLISH[2])
    assert r.status_code in (200, 302)
    with sqlite3.connect(app.config["SQLALCHEMY_DATABASE_URI"].removeprefix("sqlite:///")) as con:
        texts = [json.loads(p)["text"] for (p,) in con.execute("SELECT payload FROM events WHERE type = 'search'")]
        assert texts == SQLISH
        assert con.execute("SELECT COUNT(*) FROM participants").fetchone()[0] == 2


def test_frame_ancestors_follow_the_setting(tmp_path, demo_resources, monkeypatch):
    monkeypatch.setenv("SCENESUGGEST_FRAME_ANCESTORS", "https://app.prolific.com")
    app = make_app(tmp_path)
    csp = app.test_client().get("/study/demo/start?pid=x").headers["Content-Security-Policy"]
    assert "frame-ancestors https://app.prolific.com" in csp and "script-src 'self'" in csp
    assert "unsafe-inline" not in csp.split("script-src")[1].split(";")[0]


def test_production_needs_a_secret_from_the_environment(tmp_path, demo_resources, monkeypatch):
    monkeypatch.setenv("SCENESUGGEST_ENV", "production")
    monkeypatch.delenv("SCENESUGGEST_SECRET_KEY", raising=False)
    with pytest.raises(ConfigError, match="SCENESUGGEST_SECRET_KEY"):
        create_app({"INSTANCE_PATH": str(tmp_path / "i"), "CHECK_RESOURCES": False})
    monkeypatch.setenv("SCENESUGGEST_SECRET_KEY", "short")
    with pytest.raises(ConfigError, match="at least 32"):
        create_app({"INSTANCE_PATH": str(tmp_path / "i"), "CHECK_RESOURCES": False})
    monkeypatch.setenv("SCENESUGGEST_SECRET_KEY", "k" * 40)
    app = make_app(tmp_path)
    assert app.config["SESSION_COOKIE_SECURE"] and not app.debug
    cookie = app.test_client().get("/study/demo/start?pid=y").headers.get("Set-Cookie", "")
    assert "Secure" in cookie and "HttpOnly" in cookie and "SameSite=Lax" in cookie
    monkeypatch.setenv("SCENESUGGEST_ENV", "staging")
    with pytest.raises(ConfigError, match="SCENESUGGEST_ENV"):
        create_app({"INSTANCE_PATH": str(tmp_path / "i"), "CHECK_RESOURCES": False})


def test_development_cookies_are_httponly_and_never_debug(client):
    r = client.get("/study/demo/start?pid=z")
    cookie = r.headers.get("Set-Cookie", "")
    assert "HttpOnly" in cookie and "SameSite=Lax" in cookie
    assert not client.application.debug



def test_a_planted_session_cookie_does_not_make_the_victim_the_attacker(app):
    attacker, victim = app.test_client(), app.test_client()
    attacker_boot = to_trials(attacker, query="pid=attacker")
    cookie = attacker.get_cookie("session")
    victim.set_cookie("session", cookie.value)  # fixation: the victim's browser carries the attacker's session
    victim_boot = to_trials(victim, query="pid=victim")
    assert victim_boot["token"] != attacker_boot["token"]
    with app.app_context():
        from study_server.base.extensions import db
        from study_server.base.models import Participant

        people = {p.platform_id: p.token for p in db.session.query(Participant)}
    assert people == {"attacker": attacker_boot["token"], "victim": victim_boot["token"]}
    # the attacker's copy of the cookie still belongs to the attacker alone, who is still at their own trial
    own = attacker.get("/api/session", headers={"Authorization": f"Bearer {attacker_boot['token']}"})
    assert own.status_code == 200 and own.json["step"] == "trial"
    assert own.json["trial"]["index"] == attacker_boot["trial"]["index"]
    assert boot(enter(attacker, query="pid=attacker"))["token"] == attacker_boot["token"]


def test_the_api_and_model_files_neither_read_nor_refresh_the_cookie_session(client):
    """A participant's browser sends its (permanent) session cookie with every API call and model file: pages
    refresh it; the token-authenticated API and the models (which nginx caches only without a Set-Cookie) answer
    without one, and a cookie that is not ours changes nothing there."""
    b = to_trials(client)
    assert "session=" in client.get("/study/demo/").headers.get("Set-Cookie", "")
    model = client.get("/api/models", headers=auth(b)).json["models"][0]
    for url in (model["asset"], model["thumbnail"]):
        r = client.get(url)
        assert r.status_code == 200 and "Set-Cookie" not in r.headers and "Cookie" not in r.headers.get("Vary", "")
    for path, method in (("/api/heartbeat", client.post), ("/api/session", client.get), ("/api/models", client.get)):
        r = method(path, headers=auth(b))
        assert r.status_code == 200 and "Set-Cookie" not in r.headers and "Cookie" not in r.headers.get("Vary", "")
    client.set_cookie("session", "forged.value.here")
    r = client.post("/api/heartbeat", headers=auth(b))
    assert r.status_code == 200 and "Set-Cookie" not in r.headers
    assert client.post("/api/heartbeat").status_code == 401  # the cookie alone is nobody


def test_no_secret_or_instance_data_is_tracked():
    import re
    import subprocess

    from support import ROOT

    files = subprocess.run(["git", "ls-files"], capture_output=True, text=True, cwd=ROOT).stdout.split()
    assert files, "the repository's files are listed by git (run the tests from a checkout)"
    assert not [f for f in files if f.startswith("var/") or f.endswith((".sqlite3", "secret_key", "admin.json",
                                                                         "admin-password.txt", ".pem", ".env"))]
    assigned = re.compile(r"""(SECRET_KEY|PASSWORD|TOKEN)\w*["']?\s*[:=]\s*["'][A-Za-z0-9+/_\-]{24,}["']""")
    for name in files:
        path = ROOT / name
        if path.suffix in (".py", ".toml", ".json", ".md", ".js", ".html", ".cfg", ".ini", ".yml", ".yaml", ""):
            text = path.read_text(errors="ignore") if path.is_file() else ""
            assert not assigned.search(text), name
