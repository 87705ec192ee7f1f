"""A study served for real: nginx (Debian's, with the configuration ``study deploy-files`` writes) terminating TLS on
127.0.0.1 in front of two gunicorn app servers (separate processes, ports) on one PostgreSQL database. A participant
completes the demo in Chromium over https; the admin login limit counts the real client through the proxy and a
spoofed X-Forwarded-For buys nothing; killing one app server mid-study loses nothing."""

import json
import signal
import ssl
import threading
import time
import urllib.error
import urllib.request
from http.client import HTTPException

import pytest
from demostudy import make_app
from flowhelp import DEMOGRAPHICS
from integrityhelp import PASSWORD
from serverproc import NginxProxy, StudyServer, nginx_missing
from sqlalchemy import create_engine, text
from support import lacking
from werkzeug.security import generate_password_hash

from simulation.page import read_page
from simulation.run import simulate
from simulation.transport import HttpTransport
from simulation.walker import Walker

from .pagehelp import (
    ARGS,
    CHROMIUM,
    done,
    exit_survey,
    new_context,
    place_with_suggestions,
    ready,
    require_browser,
    start,
)

pytestmark = pytest.mark.slow


@pytest.fixture
def deployment(tmp_path, postgres_db, monkeypatch, demo_resources):
    """(nginx, [app servers], database URL); urllib in this process trusts the proxy's certificate."""
    problem = nginx_missing()
    if problem:
        lacking(problem)
    make_app(tmp_path, postgres_db)  # migrated before the app servers start
    env = {"SCENESUGGEST_PROXY_HOPS": "1", "SCENESUGGEST_ENV": "production", "SCENESUGGEST_SERVER_NAME": "127.0.0.1",
           "SCENESUGGEST_ADMIN_PASSWORD_HASH": generate_password_hash(PASSWORD)}
    apps = [StudyServer(tmp_path / f"instance-{i}", postgres_db, workers=1, migrate=False, env=env)
            for i in range(2)]
    proxy = NginxProxy(tmp_path / "nginx", [a.port for a in apps])
    monkeypatch.setenv("SSL_CERT_FILE", str(proxy.cert))
    try:
        for a in apps:
            a.start().wait_ready()
        proxy.start()
        yield proxy, apps, postgres_db
    finally:
        proxy.stop()
        for a in apps:
            if a.proc.poll() is None:
                a.kill(signal.SIGTERM)


def fetch(url, headers=None, data=None):
    """(status, headers, body) without following redirects."""
    class Stay(urllib.request.HTTPRedirectHandler):
        def redirect_request(self, *args, **kwargs):
            return None
    opener = urllib.request.build_opener(Stay, urllib.request.HTTPSHandler(context=ssl.create_default_context()))
    try:
        with opener.open(urllib.request.Request(url, data=data, headers=headers or {}), timeout=30) as r:
            return r.status, r.headers, r.read()
    except urllib.error.HTTPError as e:
        return e.code, e.headers, e.read()


def test_behind_nginx_over_https_on_postgresql(deployment):
    proxy, apps, database = deployment
    status, headers, _ = fetch(f"{proxy.http}/study/demo/start?pid=x")
    assert status == 301 and headers["Location"] == f"{proxy.https}/study/demo/start?pid=x"
    for base in (proxy.http, proxy.https):  # another host name: closed unanswered, never redirected or linked to
        with pytest.raises((urllib.error.URLError, ConnectionError, HTTPException)):
            fetch(f"{base}/study/demo/start?pid=x", {"Host": "evil.example"})
        status, headers, _ = fetch(f"{base}/study/demo/start?pid=x", {"X-Forwarded-Host": "evil.example"})
        assert "evil" not in headers.get("Location", ""), headers["Location"]
    status, headers, body = fetch(f"{proxy.https}/healthz")
    assert status == 200 and b'"ok":true' in body.replace(b" ", b"")
    assert headers["Strict-Transport-Security"] == "max-age=31536000"
    status, headers, _ = fetch(f"{proxy.https}/static/js/trial.js", {"Accept-Encoding": "gzip"})
    assert status == 200 and headers["Content-Encoding"] == "gzip" and "max-age=3600" in headers["Cache-Control"]
    assert fetch(f"{proxy.https}/vendor/three/package.json")[0] == 404

    # a participant's model files come from nginx's cache: the app answers them without refreshing the session
    http = HttpTransport(proxy.https)
    token = Walker(http, "demo").to_first_trial({"pid": "cached"}, lambda _: DEMOGRAPHICS).boot["token"]
    cookie = "; ".join(f"{c.name}={c.value}" for c in http.jar)
    assert "session=" in cookie
    model = json.loads(fetch(f"{proxy.https}/api/models", {"Authorization": f"Bearer {token}"})[2])["models"][0]
    answers = [fetch(proxy.https + model["asset"], {"Cookie": cookie})[1] for _ in range(2)]
    assert "Set-Cookie" not in answers[0] and answers[1]["X-Cache-Status"] == "HIT", dict(answers[1])

    # the admin login limit: the client nginx saw, whatever it claims to be
    guesses = []
    for i in range(7):
        http = HttpTransport(proxy.https)
        page = read_page(http.get("/admin/login").body)
        guesses.append(http.post("/admin/login", form={"csrf_token": page.csrf, "password": "guess"},
                                 headers={"X-Forwarded-For": f"198.51.100.{i}"}).status)
    assert guesses == [401] * 5 + [429] * 2

    # one app server killed mid-study: nginx sends the rest to the other, the bots send again what failed
    result = {}
    bots = threading.Thread(target=lambda: result.update(simulate(3, seed=11, study="demo", url=proxy.https)))
    bots.start()
    engine = create_engine(database)
    try:
        deadline = time.monotonic() + 120
        while time.monotonic() < deadline and bots.is_alive():
            with engine.connect() as con:
                if con.execute(text("SELECT COUNT(*) FROM events")).scalar() > 300:
                    break
            time.sleep(0.1)
        mid_study = bots.is_alive()
        apps[0].kill(signal.SIGKILL)
        bots.join()
        assert mid_study and apps[0].proc.poll() is not None
        assert result["completed"] == 3 and not result["failures"], result
        with engine.connect() as con:
            stored, distinct = con.execute(text(
                "SELECT COUNT(*), COUNT(DISTINCT (participant_id, seq)) FROM events")).one()
    finally:
        engine.dispose()
    assert stored == distinct == result["events"]  # none lost, none twice

    # a participant in Chromium, over https, from consent to the completion code
    require_browser()
    from playwright.sync_api import sync_playwright

    with sync_playwright() as p:
        browser = p.chromium.launch(executable_path=CHROMIUM, args=ARGS)
        context = new_context(browser, ignore_https_errors=True)
        page = context.new_page()
        problems = []
        page.on("pageerror", lambda e: problems.append(str(e)))
        start(page, proxy.https, "https-participant")
        assert page.url.startswith("https://")
        place_with_suggestions(page)
        cookies = {c["name"]: c for c in context.cookies()}
        assert cookies and all(c["secure"] for c in cookies.values())  # production cookies are Secure
        while True:
            done(page)
            if "Almost done" in page.content():
                break
            ready(page)
        code = exit_survey(page, "4", "Suggestions, oriented")
        browser.close()
    assert code == "DEMO-DONE-7F3A" and not problems, problems
