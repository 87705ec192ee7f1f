"""``/healthz``: 200 when the server can take participants, 503 with the failing check otherwise
(:mod:`study_server.base.health_checks`). Open to anyone (it tells nothing secret) and never cached."""

from __future__ import annotations

from flask import Blueprint, jsonify

from ..base.health_checks import health

bp = Blueprint("health", __name__)


@bp.get("/healthz")
def healthz():
    checks, ok = health()
    response = jsonify(checks)
    response.status_code = 200 if ok else 503
    response.headers["Cache-Control"] = "no-store"
    return response
