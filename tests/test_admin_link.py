"""The operator can always get in and nobody else can: a printed one-time link signs a browser in however many
logins a crowd has failed, once and before it expires; a number in an admin URL too big for the database is a
404, not a 500 (on SQLite and PostgreSQL)."""

from __future__ import annotations

import os
import subprocess
import sys
from datetime import timedelta

import pytest
from flowhelp import csrf
from integrityhelp import PASSWORD

from study_server.base.extensions import db
from study_server.base.models import AdminLink, utcnow
from study_server.base.security import new_admin_link


def link_for(app, lifetime=timedelta(minutes=15)) -> str:
    with app.app_context():
        return f"/admin/link/{new_admin_link(lifetime)}"


def crowd_locks_out_anonymous_logins(app, monkeypatch) -> None:
    """Ten addresses guessing until every browser without a device cookie gets 429 for the right password."""
    from study_server.base import security

    monkeypatch.setattr(security, "ANONYMOUS_LOGIN_LIMIT", 10)
    for i in range(12):
        c = app.test_client()
        c.environ_base["REMOTE_ADDR"] = f"198.51.100.{i % 10}"
        page = c.get("/admin/login")
        c.post("/admin/login", data={"csrf_token": csrf(page), "password": "guess"})
    c = app.test_client()
    page = c.get("/admin/login")
    assert c.post("/admin/login", data={"csrf_token": csrf(page), "password": PASSWORD}).status_code == 429


def test_a_one_time_link_gets_the_admin_in_through_a_lockout_once(app_on, monkeypatch):
    crowd_locks_out_anonymous_logins(app_on, monkeypatch)
    url = link_for(app_on)
    admin = app_on.test_client()
    page = admin.get(url)  # a chat app's preview fetches this: it spends nothing
    assert page.status_code == 200 and b"Sign in" in page.data
    assert admin.get(url).status_code == 200
    signed_in = admin.post(url, data={"csrf_token": csrf(page)})
    assert signed_in.status_code == 302 and signed_in.headers["Location"].endswith("/admin/")
    assert admin.get("/admin/").status_code == 200
    other = app_on.test_client()
    again = other.get(url)
    assert again.status_code == 410 and b"used or has expired" in again.data
    assert other.post(url, data={"csrf_token": csrf(other.get("/admin/login"))}).status_code == 410
    assert other.get("/admin/").status_code == 302  # the second browser is not in


def test_a_link_without_a_csrf_token_an_expired_or_an_invented_link_signs_nobody_in(app_on):
    url = link_for(app_on)
    c = app_on.test_client()
    assert c.post(url, data={}).status_code in (400, 403)  # a cross-site form cannot spend it
    page = c.get(url)
    with app_on.app_context():
        for row in db.session.query(AdminLink):
            row.expires_at = utcnow() - timedelta(seconds=1)
        db.session.commit()
    assert c.post(url, data={"csrf_token": csrf(page)}).status_code == 410
    for invented in ("/admin/link/abc", "/admin/link/" + "x" * 5000, "/admin/link/a%00b", "/admin/link/%ED%B2%80"):
        assert c.get(invented).status_code == 410
        assert c.post(invented, data={"csrf_token": csrf(c.get("/admin/login"))}).status_code == 410
    assert c.get("/admin/").status_code == 302
    with app_on.app_context(), pytest.raises(ValueError, match="up to"):
        new_admin_link(timedelta(days=2))


def test_the_command_prints_a_link_that_works(app, tmp_path):
    env = {**os.environ, "DATABASE_URL": app.config["SQLALCHEMY_DATABASE_URI"],
           "SCENESUGGEST_INSTANCE": str(tmp_path / "instance")}
    done = subprocess.run([sys.executable, "-m", "scenesuggest.cli", "study", "admin-link", "--minutes", "5",
                           "--base", "https://study.example.org/"], capture_output=True, text=True, env=env)
    assert done.returncode == 0, done.stderr
    url = done.stdout.split()[0]
    assert url.startswith("https://study.example.org/admin/link/") and "5 minutes" in done.stdout
    c = app.test_client()
    path = url.removeprefix("https://study.example.org")
    page = c.get(path)
    assert c.post(path, data={"csrf_token": csrf(page)}).status_code == 302
    from click.testing import CliRunner

    from scenesuggest.cli import main

    for bad, named in ((["--minutes", "0"], "--minutes"), (["--minutes", "99999"], "--minutes"),
                       (["--base", "study.example.org"], "--base")):
        refused = CliRunner().invoke(main, ["study", "admin-link", *bad], env=env)
        assert refused.exit_code == 2 and named in refused.output, refused.output
    elsewhere = {**env, "DATABASE_URL": f"sqlite:///{tmp_path / 'never-migrated.sqlite3'}"}
    refused = CliRunner().invoke(main, ["study", "admin-link"], env=elsewhere)
    assert refused.exit_code == 2 and "no admin_links table" in refused.output, refused.output


@pytest.mark.parametrize("number", ["2147483648", "9223372036854775808", "99999999999999999999999"])
def test_numbers_too_big_for_the_database_in_admin_urls_are_404(app_on, number):
    admin = app_on.test_client()
    page = admin.get("/admin/login")
    admin.post("/admin/login", data={"csrf_token": csrf(page), "password": PASSWORD})
    for path in (f"/admin/demo/participants/{number}", f"/admin/demo/participants/1/trials/{number}/replay",
                 f"/admin/demo/participants/{number}/trials/0/replay.json",
                 f"/admin/demo/participants/1/trials/-{int(number) + 1}/replay.json"):
        assert admin.get(path).status_code == 404, path
    page = admin.get("/admin/")
    assert admin.post(f"/admin/demo/participants/{number}/exclude",
                      data={"csrf_token": csrf(page), "reason": "x"}).status_code == 404
    assert admin.get("/admin/demo/participants/2147483647").status_code == 404  # the largest: looked up, absent
