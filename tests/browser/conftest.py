"""Fixtures of the browser tests: Playwright driving Debian's Chromium (WebGL on SwiftShader) against the study
server run as `make serve` runs it, and the trial page's test hook."""

from __future__ import annotations

import pytest
from demostudy import copy_demo_study, gunicorn, make_app

from .pagehelp import ARGS, CHROMIUM, IGNORED_CONSOLE, new_context, require_browser


@pytest.fixture(scope="module")
def server(tmp_path_factory, demo_resources):
    """gunicorn with 2 workers on a fresh SQLite database; yields (base URL, database path)."""
    require_browser()
    with gunicorn(tmp_path_factory.mktemp("browser")) as running:
        yield running


@pytest.fixture(scope="module")
def browser(server):
    from playwright.sync_api import sync_playwright

    with sync_playwright() as p:  # launch() gives the browser a fresh temporary profile
        b = p.chromium.launch(executable_path=CHROMIUM, args=ARGS)
        yield b
        b.close()


@pytest.fixture
def page(browser):
    context = new_context(browser)
    pg = context.new_page()
    pg.console_problems = []
    pg.on("console", lambda m: m.type == "error" and not any(s in m.text for s in IGNORED_CONSOLE)
          and pg.console_problems.append(m.text))
    pg.on("pageerror", lambda e: pg.console_problems.append(str(e)))
    yield pg
    context.close()


# --- the replication study and the admin's scene editor --------------------------------------------------------
@pytest.fixture(scope="module")
def replication_server(tmp_path_factory, replication):
    """gunicorn serving the SceneSuggest replication (Stanford representatives) on a fresh SQLite database."""
    from serverproc import StudyServer

    require_browser()
    tmp = tmp_path_factory.mktemp("replication")
    make_app(tmp, f"sqlite:///{tmp / 'study.sqlite3'}", studies=[replication])
    with StudyServer(tmp / "instance", f"sqlite:///{tmp / 'study.sqlite3'}", migrate=False, study=replication) as s:
        yield s.base


@pytest.fixture
def authoring_server(tmp_path, demo_resources):
    """gunicorn serving a copy of the demo study (its targets get written) with an admin password."""
    from serverproc import StudyServer
    from werkzeug.security import generate_password_hash

    require_browser()
    folder = copy_demo_study(tmp_path).parent
    make_app(tmp_path, f"sqlite:///{tmp_path / 'study.sqlite3'}", studies=[folder / "study.toml"])
    server = StudyServer(tmp_path / "instance", f"sqlite:///{tmp_path / 'study.sqlite3'}", migrate=False,
                         study=folder / "study.toml")
    server.env["SCENESUGGEST_ADMIN_PASSWORD_HASH"] = generate_password_hash("author-password")
    with server:
        yield server.base, folder


@pytest.fixture(scope="module")
def replication_admin(tmp_path_factory, replication):
    """gunicorn serving the replication with an admin password, for its scene editor (the full condition)."""
    from serverproc import StudyServer
    from werkzeug.security import generate_password_hash

    require_browser()
    tmp = tmp_path_factory.mktemp("replication-admin")
    make_app(tmp, f"sqlite:///{tmp / 'study.sqlite3'}", studies=[replication])
    server = StudyServer(tmp / "instance", f"sqlite:///{tmp / 'study.sqlite3'}", migrate=False, study=replication)
    server.env["SCENESUGGEST_ADMIN_PASSWORD_HASH"] = generate_password_hash("author-password")
    with server:
        yield server.base
