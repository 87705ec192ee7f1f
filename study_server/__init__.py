"""The study server: ``create_app()`` builds everything; nothing happens at import.

Blueprints: ``participant`` (pages under /study/<id>/), ``api`` (JSON under /api/), ``admin`` (/admin/).
"""

from __future__ import annotations

import gc
import os
from pathlib import Path

from flask import Flask
from sqlalchemy import event
from werkzeug.exceptions import HTTPException

from .base import config as settings
from .base.extensions import Answers, db, json_text, json_value, migrate

MIGRATIONS = settings.MIGRATIONS


def _sqlite_pragmas(dbapi_connection, _record) -> None:
    cursor = dbapi_connection.cursor()
    cursor.execute("PRAGMA journal_mode=WAL")
    cursor.execute("PRAGMA synchronous=NORMAL")
    cursor.execute("PRAGMA busy_timeout=10000")
    cursor.execute("PRAGMA foreign_keys=ON")
    cursor.close()


def _private_sqlite_file(url: str) -> None:
    """Create the SQLite database file readable by its owner only (0600); SQLite gives its WAL and shared-memory
    files the database file's permissions."""
    import sqlite3

    from sqlalchemy.engine import make_url

    if sqlite3.sqlite_version_info < (3, 35, 0):  # ingestion needs INSERT … RETURNING
        raise settings.ConfigError(f"SQLite {sqlite3.sqlite_version} is too old (3.35 or newer is needed); use a "
                                   "newer Python or PostgreSQL", field="DATABASE_URL")
    name = make_url(url).database
    if not name or name == ":memory:" or name.startswith("file:"):
        return
    path = Path(name)
    path.parent.mkdir(parents=True, exist_ok=True)
    os.close(os.open(path, os.O_WRONLY | os.O_CREAT, 0o600))
    if path.stat().st_uid == os.getuid():
        path.chmod(0o600)


def _check_driver(url: str) -> None:
    """PostgreSQL needs its driver, an optional dependency: say how to install it instead of a traceback."""
    import importlib.util

    if url.startswith("postgresql") and importlib.util.find_spec("psycopg") is None:
        raise settings.ConfigError("names PostgreSQL, whose driver is not installed: pip install "
                                   "'scenesuggest-studio[postgres]' (or the wheel file with [postgres] after it)",
                                   field="DATABASE_URL")


def _trust_proxies(app: Flask, hops: int) -> None:
    """Take the client's address, scheme and port from the X-Forwarded-* headers of ``hops`` reverse proxies."""
    from werkzeug.middleware.proxy_fix import ProxyFix

    # never X-Forwarded-Host: the proxy sets Host (to the one name it serves), and a client's own claim of a
    # host would otherwise name it in the links the app writes
    app.wsgi_app = ProxyFix(app.wsgi_app, x_for=hops, x_proto=hops, x_host=0, x_port=hops)


def _warm_studies(app: Flask) -> None:
    """Load every study's resources now, then exempt them from the garbage collector's full collections."""
    for study_runtime in app.extensions["studies"].values():
        study_runtime.warm()
    # what is loaded now lives as long as the process: the collector need never walk it again (a full
    # collection over it took ~0.1 s, a pause in whichever request set it off); garbage goes first
    gc.collect()
    gc.freeze()


def create_app(config: dict | None = None) -> Flask:
    """Build the app. ``config`` overrides the environment (tests pass a database URL and study files)."""
    instance = Path((config or {}).get("INSTANCE_PATH") or settings.instance_path())
    app = Flask(__name__, instance_path=str(instance))  # templates/ and static/ of the package
    app.json = Answers(app)
    app.config.update(settings.from_environment(instance))
    app.config.update(config or {})
    # a relative SQLite path: a command line's --db is relative to where it runs; DATABASE_URL's to the instance
    # folder (Flask-SQLAlchemy's meaning); made absolute here, so that every part of the app opens the same file
    app.config["SQLALCHEMY_DATABASE_URI"] = settings.absolute_sqlite(
        app.config["SQLALCHEMY_DATABASE_URI"],
        Path.cwd() if app.config.get("DATABASE_FROM_COMMAND_LINE") else Path(app.instance_path))
    options = app.config.setdefault("SQLALCHEMY_ENGINE_OPTIONS", {})
    options.setdefault("json_serializer", json_text)
    options.setdefault("json_deserializer", json_value)
    _check_driver(app.config["SQLALCHEMY_DATABASE_URI"])
    if app.config["SQLALCHEMY_DATABASE_URI"].startswith("sqlite"):
        options.setdefault("connect_args", {"timeout": 10})
        _private_sqlite_file(app.config["SQLALCHEMY_DATABASE_URI"])
    db.init_app(app)
    migrate.init_app(app, db, directory=str(MIGRATIONS))
    with app.app_context():
        if db.engine.dialect.name == "sqlite":
            event.listen(db.engine, "connect", _sqlite_pragmas)

    from .studies.served import load_studies

    app.extensions["studies"] = load_studies(app.config["STUDY_FILES"], check=app.config.get("CHECK_RESOURCES", True))

    from .base import i18n

    i18n.init_app(app)

    from scenesuggest.contract.events import SEND_BATCH

    from .base import errors
    from .base.importmap import IMPORT_MAP
    from .base.security import CookieSessions, csrf_token, security_headers
    from .base.urls import RowNumber
    from .blueprints import admin, api, health, participant, vendor
    from .participants.arrival import MTURK_SUBMIT
    from .participants.boot import api_base

    app.url_map.converters["row"] = RowNumber
    app.register_blueprint(vendor.bp)
    app.register_blueprint(participant.bp)
    app.register_blueprint(api.bp)
    app.register_blueprint(admin.bp)
    app.register_blueprint(health.bp)
    hops = app.config.get("PROXY_HOPS", 0)
    if hops:  # behind that many reverse proxies: their X-Forwarded-* say the client's address, scheme and port
        _trust_proxies(app, hops)
    app.session_interface = CookieSessions()
    app.after_request(security_headers)
    app.jinja_env.globals["csrf_token"] = csrf_token
    app.jinja_env.globals["api_base"] = api_base
    app.jinja_env.globals["import_map"] = IMPORT_MAP
    app.jinja_env.globals["mturk_submit_hosts"] = MTURK_SUBMIT
    app.jinja_env.globals["event_batch"] = SEND_BATCH
    app.register_error_handler(errors.StudyError, errors.answer)
    app.register_error_handler(HTTPException, errors.http_error)
    app.register_error_handler(Exception, errors.unexpected)
    if app.config.get("WARM_STUDIES") and app.config.get("CHECK_RESOURCES", True):  # a server, not a command
        _warm_studies(app)
    return app


def upgrade_database(app: Flask) -> None:
    """Create or migrate the schema to the newest revision (run before starting workers)."""
    from flask_migrate import upgrade

    with app.app_context():
        upgrade(directory=str(MIGRATIONS))
