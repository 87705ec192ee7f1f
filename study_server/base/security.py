"""Tokens (participants' CSRF, admin previews), admin login and sessions, and HTTP security headers."""

from __future__ import annotations

import hashlib
import hmac
import ipaddress
import re
import secrets
from dataclasses import dataclass
from datetime import timedelta
from functools import wraps

from flask import abort, current_app, redirect, request, session, url_for
from flask.sessions import NullSession, SecureCookieSessionInterface
from itsdangerous import BadSignature, URLSafeTimedSerializer
from sqlalchemy import delete, func, or_, select, update
from werkzeug.security import check_password_hash

from .errors import StudyError
from .extensions import db
from .importmap import IMPORT_MAP_HASH
from .models import AdminLink, AdminSession, LoginAttempt, utcnow

#: Failed admin logins allowed per client (device or address) within the window before answering 429.
LOGIN_LIMIT = 5
LOGIN_WINDOW = timedelta(minutes=15)
#: Failed logins from all clients without a device cookie together, within the window.
ANONYMOUS_LOGIN_LIMIT = 50
#: An admin session ends after this long, or after this long without a request.
ADMIN_LIFETIME = timedelta(hours=8)
ADMIN_IDLE = timedelta(hours=1)
DEVICE_COOKIE = "scenesuggest_admin_device"
DEVICE_SALT = "scenesuggest-admin-device"
DEVICE_LIFETIME = timedelta(days=365)
#: How long a printed one-time sign-in link works (``scenesuggest study admin-link``), by default and at most.
ADMIN_LINK_LIFETIME = timedelta(minutes=15)
ADMIN_LINK_LONGEST = timedelta(hours=24)


def csrf_token() -> str:
    """The form token of this browser session (rendered into every form that changes state)."""
    if "csrf" not in session:
        session["csrf"] = secrets.token_urlsafe(24)
    return session["csrf"]


def csrf_ok(sent: str | None) -> bool:
    """Whether ``sent`` is this browser session's form token."""
    return bool(sent) and hmac.compare_digest(sent.encode(), session.get("csrf", "").encode())


def check_csrf() -> None:
    """A state-changing form must carry this session's token."""
    if not csrf_ok(request.form.get("csrf_token", "")):
        from flask_babel import gettext

        abort(400, gettext("The form has expired; please go back and try again."))


def client_ip() -> str:
    """The client's address: what the believed proxies say it is when that is an IP address, else the address
    of whoever connected (a string a client put in X-Forwarded-For never keys a quota)."""
    for address in (request.remote_addr, request.environ.get("werkzeug.proxy_fix.orig", {}).get("REMOTE_ADDR")):
        try:
            return str(ipaddress.ip_address((address or "").split("%", 1)[0]))
        except ValueError:
            continue
    return "unknown"


def client_network() -> str:
    """The client's address as limits count it: an IPv6 client by its /64 (one subscriber's whole block)."""
    address = client_ip()
    try:
        ip = ipaddress.ip_address(address)
    except ValueError:
        return address
    if ip.version == 6:
        if ip.ipv4_mapped is not None:
            return str(ip.ipv4_mapped)
        return str(ipaddress.ip_network(f"{ip}/64", strict=False))
    return str(ip)


def address_key() -> str:
    """A keyed hash of the client's address: enough to count arrivals per address, not the address itself."""
    key = current_app.config["SECRET_KEY"].encode()
    return hmac.new(key, client_network().encode(), "sha256").hexdigest()[:32]


PREVIEW_SALT = "scenesuggest-preview"
#: How long an admin's preview link works.
PREVIEW_LIFETIME = timedelta(hours=12)


def _signer(salt: str) -> URLSafeTimedSerializer:
    return URLSafeTimedSerializer(current_app.config["SECRET_KEY"], salt=salt)


def preview_token(study_id: str, condition: str, scene: str) -> str:
    """A signed token that lets the admin's preview page use the API for one condition × scene, storing nothing."""
    return "preview." + _signer(PREVIEW_SALT).dumps([study_id, condition, scene])


@dataclass(frozen=True)
class Preview:
    """An admin's look at one condition × scene of a study: everything works, nothing is stored."""

    study_id: str
    condition: str
    scene: str


def read_preview_token(token: str) -> Preview | None:
    """The preview a valid preview token grants, else None."""
    try:
        study_id, condition, scene = _signer(PREVIEW_SALT).loads(token.removeprefix("preview."),
                                                                 max_age=PREVIEW_LIFETIME.total_seconds())
    except (BadSignature, ValueError, TypeError):
        return None
    return Preview(study_id, condition, scene)


class LoginBlocked(StudyError):
    """Too many failed logins from this client within the window."""

    status = 429

    def __init__(self):
        super().__init__("too many failed attempts", "password")


def _client_key() -> str:
    """Whom failed logins are counted against: a browser that has logged in before (its signed device cookie),
    else the client's address. Guesses from one address (behind a proxy: everyone's) then never lock out an
    admin's own browser (OWASP's device cookies)."""
    device = request.cookies.get(DEVICE_COOKIE)
    if device:
        try:
            return "device:" + _signer(DEVICE_SALT).loads(device, max_age=DEVICE_LIFETIME.total_seconds())[:48]
        except (BadSignature, TypeError):
            pass
    return "ip:" + client_network()


def attempt_login(password: str) -> str | None:
    """Check the admin password (constant time via werkzeug) and on success start a fresh admin session (a new
    session id: no fixation); returns a device cookie value for the browser on success, None on failure. Raises
    :class:`LoginBlocked` after ``LOGIN_LIMIT`` failures of this client in ``LOGIN_WINDOW``. The attempt is
    recorded before the password is checked, so parallel guesses are counted, never given extra tries."""
    key = _client_key()
    attempt = LoginAttempt(ip=key, ok=None, at=utcnow())
    db.session.add(attempt)
    db.session.commit()
    failing = (or_(LoginAttempt.ok.is_(False), LoginAttempt.ok.is_(None)), LoginAttempt.at >= utcnow() - LOGIN_WINDOW)
    counted = db.session.scalar(select(func.count()).select_from(LoginAttempt).where(LoginAttempt.ip == key, *failing))
    # clients without a device cookie also share one cap, so that many addresses do not buy many guesses
    anonymous = db.session.scalar(select(func.count()).select_from(LoginAttempt).where(
        LoginAttempt.ip.like("ip:%"), *failing)) if key.startswith("ip:") else 0
    if counted > LOGIN_LIMIT or anonymous > ANONYMOUS_LOGIN_LIMIT:
        db.session.delete(attempt)
        db.session.commit()
        raise LoginBlocked()
    expected = current_app.config.get("ADMIN_PASSWORD_HASH")
    ok = bool(expected) and check_password_hash(expected, password)
    attempt.ok = ok
    if not ok:
        db.session.commit()
        return None
    return _start_admin_session(key)


def _start_admin_session(key: str) -> str:
    """Sign this browser in: a fresh admin session (a new session id: no fixation); returns the value of its
    device cookie."""
    sid = secrets.token_urlsafe(32)
    db.session.add(AdminSession(id=_digest(sid), created_at=utcnow(), last_seen_at=utcnow()))
    db.session.commit()
    session.clear()
    session["admin"] = sid
    session["csrf"] = secrets.token_urlsafe(24)
    session.permanent = False
    device = key.removeprefix("device:") if key.startswith("device:") else secrets.token_urlsafe(16)
    return _signer(DEVICE_SALT).dumps(device)


def new_admin_link(lifetime: timedelta = ADMIN_LINK_LIFETIME) -> str:
    """A new one-time sign-in secret, working for ``lifetime`` (the database keeps only its digest); links that
    have expired are forgotten."""
    if not timedelta(0) < lifetime <= ADMIN_LINK_LONGEST:
        raise ValueError(f"a sign-in link works for up to {ADMIN_LINK_LONGEST}")
    secret = secrets.token_urlsafe(32)
    now = utcnow()
    db.session.execute(delete(AdminLink).where(AdminLink.expires_at < now))
    db.session.add(AdminLink(id=_digest(secret), created_at=now, expires_at=now + lifetime))
    db.session.commit()
    return secret


def admin_link_live(secret: str) -> bool:
    row = db.session.get(AdminLink, _digest(secret))
    return row is not None and row.used_at is None and row.expires_at > utcnow()


def use_admin_link(secret: str) -> str | None:
    """Sign in with a one-time link: only once (one UPDATE claims it, so two browsers racing get one session)
    and before it expires, whatever failed logins have done. Returns a device cookie value, or None."""
    now = utcnow()
    claimed = db.session.execute(update(AdminLink).where(
        AdminLink.id == _digest(secret), AdminLink.used_at.is_(None), AdminLink.expires_at > now).values(used_at=now))
    db.session.commit()
    if claimed.rowcount != 1:
        return None
    return _start_admin_session(_client_key())


def _digest(sid: str) -> str:
    return hashlib.sha256(sid.encode()).hexdigest()


def admin_session() -> AdminSession | None:
    """This browser's admin session if it is live (not logged out, not idle too long, not too old)."""
    sid = session.get("admin")
    if not isinstance(sid, str):
        return None
    row = db.session.get(AdminSession, _digest(sid))
    now = utcnow()
    if row is None or row.created_at is None or row.last_seen_at is None or now - row.created_at > ADMIN_LIFETIME \
            or now - row.last_seen_at > ADMIN_IDLE:  # a time that cannot be read (column_types) ends the session
        if row is not None:
            db.session.delete(row)
            db.session.commit()
        return None
    if now - row.last_seen_at > timedelta(minutes=1):
        row.last_seen_at = now
        db.session.commit()
    return row


def end_admin_session() -> None:
    """Log out: the server forgets the session, so a copy of the cookie is worthless."""
    sid = session.get("admin")
    if isinstance(sid, str):
        db.session.execute(delete(AdminSession).where(AdminSession.id == _digest(sid)))
        db.session.commit()
    session.clear()


def admin_required(view):
    @wraps(view)
    def wrapped(*args, **kwargs):
        if admin_session() is None:
            session.pop("admin", None)
            return redirect(url_for("admin.login", next=request.path))
        return view(*args, **kwargs)
    return wrapped


class _NoSession(NullSession):
    """The session of a request that has none: reading finds nothing, writing is a programming error."""

    def _fail(self, *args, **kwargs):
        raise RuntimeError("this request has no cookie session (the JSON API and model assets: CookieSessions)")

    __setitem__ = __delitem__ = clear = pop = popitem = update = setdefault = _fail


#: Requests that never read or refresh the cookie session: the JSON API (it authenticates by token) and the model
#: assets (their answers must carry no Set-Cookie, or no proxy caches them).
SESSIONLESS = re.compile(r"/api/|/study/[^/]+/assets/")


class CookieSessions(SecureCookieSessionInterface):
    """Flask's signed-cookie sessions, left out of requests that need none (:data:`SESSIONLESS`): a participant's
    permanent session was read and answered with a refreshed Set-Cookie (and ``Vary: Cookie``) on every event
    batch and every model file, which kept nginx from caching the models. Pages refresh it as before."""

    null_session_class = _NoSession

    def open_session(self, app, request):
        if SESSIONLESS.match(request.path):
            return self.null_session_class()
        return super().open_session(app, request)


def security_headers(response):
    """CSP allowing only this origin's scripts (and the one import map, by hash); frame-ancestors as configured
    for embedding platforms."""
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
