"""What ``/healthz`` checks, for a load balancer or a process supervisor: the database answers, its schema is at
the newest revision this code knows, and every study's priors and model library are loaded. The answer names
each check and says ``ok`` or what failed, by kind only: no URL, path, version string or message that could help
an attacker."""

from __future__ import annotations

from flask import Flask, current_app
from sqlalchemy import inspect, text
from sqlalchemy.exc import SQLAlchemyError

from .extensions import db


def head_revision(app: Flask) -> str:
    """The newest migration revision of this code (read once per app)."""
    if "head_revision" not in app.extensions:
        from alembic.script import ScriptDirectory

        from .config import MIGRATIONS

        app.extensions["head_revision"] = ScriptDirectory(str(MIGRATIONS)).get_current_head()
    return app.extensions["head_revision"]


def _database() -> tuple[str, str]:
    """(database check, schema check)."""
    try:
        db.session.execute(text("SELECT 1"))
        migrated = inspect(db.session.connection()).has_table("alembic_version")
        revision = db.session.execute(text("SELECT version_num FROM alembic_version")).scalar() if migrated else None
    except SQLAlchemyError:
        db.session.rollback()
        return "unreachable", "unknown"
    if not migrated:
        return "ok", "not migrated"
    if revision == head_revision(current_app):
        return "ok", "ok"
    return "ok", "behind: run 'scenesuggest study migrate'"


def _study(rt) -> str:
    try:
        loaded = rt.priors is not None and rt.library is not None  # loaded once per process; cached after
    except Exception as e:  # noqa: BLE001 - reported by kind, never raised
        return f"unavailable ({type(e).__name__})"
    return "ok" if loaded else "unavailable"


def _engines(rt) -> dict[str, dict]:
    """The study's engines by name (not by condition: which condition runs which engine is the experimenter's
    business): version and status — ``ok`` once loaded (an HTTP engine: with how many of its answers this process
    replaced by its fallback's), ``not loaded yet`` before first use, or what kind of failure stopped its
    loading. Nothing is loaded by asking."""
    loaded = rt.loaded_engines()
    out: dict[str, dict] = {}
    for c in rt.study.conditions:
        if c.mode is None:
            continue
        entry = out.setdefault(c.engine.name, {"version": c.engine.kind.version, "status": "not loaded yet"})
        if c.id in rt.engine_failures:
            entry["status"] = f"unavailable ({rt.engine_failures[c.id].split(':')[0]})"
        elif c.id in loaded and not entry["status"].startswith("unavailable"):
            entry["status"] = "ok"
            if hasattr(loaded[c.id], "fallbacks"):
                entry["fallbacks"] = entry.get("fallbacks", 0) + loaded[c.id].fallbacks
    return out


def health() -> tuple[dict, bool]:
    """The checks and whether all passed."""
    database, schema = _database()
    runtimes = current_app.extensions["studies"]
    studies = {sid: _study(rt) for sid, rt in runtimes.items()}
    engines = {sid: _engines(rt) for sid, rt in runtimes.items()}
    ok = (database == "ok" and schema == "ok" and all(v == "ok" for v in studies.values())
          and not any(e["status"].startswith("unavailable") for per in engines.values() for e in per.values()))
    return {"ok": ok, "database": database, "schema": schema, "studies": studies, "engines": engines}, ok
