"""Nobody can get into the experimenter's side: admin logins are rate-limited per client however the guesses
come, an admin session ends at logout and when idle, redirects and asset paths stay inside the study, and the
database and admin secrets are private files. On SQLite and on PostgreSQL where storage is involved."""

from __future__ import annotations

import os
import stat
from datetime import timedelta

from demostudy import make_app
from flowhelp import csrf, enter, to_trials
from integrityhelp import PASSWORD, study_copy
from werkzeug.security import generate_password_hash

from study_server.base.extensions import db
from study_server.base.models import AdminSession, Trial, utcnow
from study_server.participants.assignment import row_counts


def test_logout_ends_the_session_on_the_server_and_sessions_expire(app_on):
    admin = app_on.test_client()
    page = admin.get("/admin/login")
    admin.post("/admin/login", data={"csrf_token": csrf(page), "password": PASSWORD})
    copied = app_on.test_client()
    copied.set_cookie("session", admin.get_cookie("session").value)
    assert copied.get("/admin/demo/export.zip").status_code == 200
    page = admin.get("/admin/")
    admin.post("/admin/logout", data={"csrf_token": csrf(page)})
    r = copied.get("/admin/demo/export.zip")
    assert r.status_code == 302 and "/admin/login" in r.headers["Location"]
    page = admin.get("/admin/login")
    admin.post("/admin/login", data={"csrf_token": csrf(page), "password": PASSWORD})
    assert admin.get("/admin/").status_code == 200
    with app_on.app_context():  # idle for more than an hour
        for s in db.session.query(AdminSession):
            s.last_seen_at = utcnow() - timedelta(hours=2)
        db.session.commit()
    assert admin.get("/admin/").status_code == 302


def test_failed_logins_from_an_address_do_not_lock_out_an_admins_browser(app_on):
    admin = app_on.test_client()  # the admin has logged in from this browser before
    page = admin.get("/admin/login")
    assert admin.post("/admin/login", data={"csrf_token": csrf(page), "password": PASSWORD}).status_code == 302
    page = admin.get("/admin/")
    admin.post("/admin/logout", data={"csrf_token": csrf(page)})
    attacker = app_on.test_client()  # same address (127.0.0.1: behind a proxy, everyone's)
    page = attacker.get("/admin/login")
    codes = [attacker.post("/admin/login", data={"csrf_token": csrf(page), "password": "guess"}).status_code
             for _ in range(8)]
    assert codes == [401] * 5 + [429] * 3
    page = attacker.get("/admin/login")
    assert attacker.post("/admin/login", data={"csrf_token": csrf(page), "password": PASSWORD}).status_code == 429
    page = admin.get("/admin/login")
    assert admin.post("/admin/login", data={"csrf_token": csrf(page), "password": PASSWORD}).status_code == 302


def test_parallel_guesses_get_no_extra_tries(tmp_path, demo_resources):
    import re
    from concurrent.futures import ThreadPoolExecutor

    import requests
    from serverproc import StudyServer

    database = f"sqlite:///{tmp_path / 'study.sqlite3'}"
    make_app(tmp_path, database)
    os.environ["SCENESUGGEST_ADMIN_PASSWORD_HASH"] = generate_password_hash(PASSWORD)
    try:
        with StudyServer(tmp_path / "instance", database, workers=3, migrate=False) as server:
            def guess(i):
                s = requests.Session()
                token = re.search(r'name="csrf_token" value="([^"]+)"', s.get(f"{server.base}/admin/login").text)
                return s.post(f"{server.base}/admin/login", data={"csrf_token": token.group(1),
                                                                  "password": f"guess{i}"}, timeout=30).status_code
            with ThreadPoolExecutor(max_workers=12) as pool:
                codes = list(pool.map(guess, range(24)))
    finally:
        del os.environ["SCENESUGGEST_ADMIN_PASSWORD_HASH"]
    assert codes.count(401) == 5 and codes.count(429) == 19, codes


def test_visitors_who_do_not_consent_hold_no_row_and_do_not_freeze_authoring(app_on):
    for i in range(20):
        enter(app_on.test_client(), query=f"pid=visitor{i}")
    with app_on.app_context():
        assert row_counts(app_on.extensions["studies"]["demo"].study, utcnow()) == [0] * 6
        assert db.session.query(Trial).count() == 0
    admin = app_on.test_client()
    page = admin.get("/admin/login")
    admin.post("/admin/login", data={"csrf_token": csrf(page), "password": PASSWORD})
    page = admin.get("/admin/demo/author/bedside")
    assert b'"frozen": 0' in page.data or b"&#34;frozen&#34;: 0" in page.data


def test_mturk_submit_hosts_and_login_next_and_asset_paths(tmp_path, demo_resources, client):
    app = make_app(tmp_path / "m", studies=[study_copy(tmp_path, platform="mturk")])
    ids = "workerId=A1B2C3D4E5F6G7&assignmentId=3AMW0RGHOD1P000000000000000000&hitId=3HYA4D452RIC111111111111111111"
    r = app.test_client().get(f"/study/demo/start?{ids}&turkSubmitTo=https://evil.example")
    assert r.status_code == 422 and b"turkSubmitTo" in r.data
    assert app.test_client().get(f"/study/demo/start?{ids}&turkSubmitTo=https://workersandbox.mturk.com"
                                 ).status_code == 302
    admin_app = make_app(tmp_path / "a", ADMIN_PASSWORD_HASH=generate_password_hash(PASSWORD))
    admin = admin_app.test_client()
    page = admin.get("/admin/login")
    r = admin.post("/admin/login?next=/admin/%0d%0aSet-Cookie:x=1", data={"csrf_token": csrf(page),
                                                                           "password": PASSWORD})
    assert r.status_code == 302 and r.headers["Location"] == "/admin/" and "Set-Cookie: x" not in str(r.headers)
    assert client.get("/study/demo/assets/models/../library.json").status_code == 404
    assert client.get("/study/demo/assets/thumbnails/../../library/library.json").status_code == 404


def test_database_files_and_admin_secrets_are_private(tmp_path, demo_resources):
    from study_server.base.config import ensure_admin_password

    os.umask(0o022)
    app = make_app(tmp_path)
    client = app.test_client()
    to_trials(client)
    files = [tmp_path / "study.sqlite3", tmp_path / "study.sqlite3-wal"]
    ensure_admin_password(tmp_path / "fresh")
    files += [tmp_path / "fresh" / "admin.json", tmp_path / "fresh" / "admin-password.txt"]
    for f in files:
        assert f.exists(), f
        assert stat.S_IMODE(f.stat().st_mode) == 0o600, (f, oct(f.stat().st_mode))
    assert stat.S_IMODE((tmp_path / "instance").stat().st_mode) == 0o700


def test_login_limits_count_an_ipv6_block_as_one_client_and_cap_all_anonymous_clients(app_on, monkeypatch):
    from study_server.base import security

    def guess(address, password="guess"):
        c = app_on.test_client()
        c.environ_base["REMOTE_ADDR"] = address
        page = c.get("/admin/login")
        return c.post("/admin/login", data={"csrf_token": csrf(page), "password": password}).status_code
    codes = [guess(f"2001:db8:0:1::{i}") for i in range(1, 8)]  # one /64: one client
    assert codes == [401] * 5 + [429] * 2
    assert guess("2001:db8:0:2::1", PASSWORD) == 302  # the next /64 is another client
    monkeypatch.setattr(security, "ANONYMOUS_LOGIN_LIMIT", 8)
    codes = [guess(f"10.0.0.{i}") for i in range(1, 6)]  # every address new: the shared cap stops them
    assert codes.count(429) >= 2 and guess("10.0.1.1", PASSWORD) == 429


def test_a_forged_or_foreign_device_cookie_buys_no_extra_guesses(app_on):
    from study_server.base.security import DEVICE_COOKIE

    def guesses(cookie):
        c = app_on.test_client()
        if cookie:
            c.set_cookie(DEVICE_COOKIE, cookie, path="/admin")
        page = c.get("/admin/login")
        return [c.post("/admin/login", data={"csrf_token": csrf(page), "password": "guess"}).status_code
                for _ in range(3)]
    assert guesses(None) + guesses(None) == [401] * 5 + [429]  # one address: five tries
    assert guesses("made-up.value.sig") == [429] * 3  # an unsigned cookie counts as the address
    assert guesses("x" * 3000) == [429] * 3  # a long one too (no 500)
