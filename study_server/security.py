"""Tokens, CSRF, admin login and HTTP security headers."""

from __future__ import annotations

import hmac
import secrets
from datetime import timedelta
from functools import wraps

from flask import abort, current_app, redirect, request, session, url_for
from sqlalchemy import func, select
from werkzeug.security import check_password_hash

from .extensions import db
from .models import LoginAttempt, utcnow

#: Failed admin logins allowed per address within the window before answering 429.
LOGIN_LIMIT = 5
LOGIN_WINDOW = timedelta(minutes=15)


def csrf_token() -> str:
    """The form token of this browser session (rendered into every form that changes state)."""
    if "csrf" not in session:
        session["csrf"] = secrets.token_urlsafe(24)
    return session["csrf"]


def csrf_ok(sent: str | None) -> bool:
    """Whether ``sent`` is this browser session's form token."""
    return bool(sent) and hmac.compare_digest(sent, session.get("csrf", ""))


def check_csrf() -> None:
    """A state-changing form must carry this session's token."""
    if not csrf_ok(request.form.get("csrf_token", "")):
        abort(400, "The form has expired; please go back and try again.")


def client_ip() -> str:
    return (request.remote_addr or "unknown")[:64]


def login_blocked(ip: str) -> bool:
    since = utcnow() - LOGIN_WINDOW
    failures = db.session.scalar(select(func.count()).select_from(LoginAttempt).where(
        LoginAttempt.ip == ip, LoginAttempt.ok.is_(False), LoginAttempt.at >= since))
    return failures >= LOGIN_LIMIT


def attempt_login(password: str) -> bool:
    """Check the admin password (constant time via werkzeug), record the attempt, and on success start a
    fresh admin session (a new session id: no fixation)."""
    expected = current_app.config.get("ADMIN_PASSWORD_HASH")
    ok = bool(expected) and check_password_hash(expected, password)
    db.session.add(LoginAttempt(ip=client_ip(), ok=ok))
    db.session.commit()
    if ok:
        session.clear()
        session["admin"] = True
        session["csrf"] = secrets.token_urlsafe(24)
        session.permanent = False
    return ok


def admin_required(view):
    @wraps(view)
    def wrapped(*args, **kwargs):
        if not session.get("admin"):
            return redirect(url_for("admin.login", next=request.path))
        return view(*args, **kwargs)
    return wrapped


def security_headers(response):
    """CSP allowing only this origin's scripts (and the one import map, by hash); frame-ancestors as configured
    for embedding platforms."""
    from .blueprints.vendor import IMPORT_MAP_HASH

    ancestors = current_app.config.get("FRAME_ANCESTORS", "'self'")
    response.headers.setdefault(
        "Content-Security-Policy",
        f"default-src 'self'; script-src 'self' '{IMPORT_MAP_HASH}'; style-src 'self'; "
        "img-src 'self' data: blob:; "
        "connect-src 'self'; worker-src 'self' blob:; object-src 'none'; base-uri 'none'; "
        f"form-action 'self' https:; frame-ancestors {ancestors}")
    response.headers.setdefault("X-Content-Type-Options", "nosniff")
    response.headers.setdefault("Referrer-Policy", "same-origin")
    if ancestors.strip() == "'self'":
        response.headers.setdefault("X-Frame-Options", "SAMEORIGIN")
    return response
