"""How the study server fails on purpose, in one convention.

Services (everything outside ``blueprints/``) raise a :class:`StudyError` subclass named for what happened in the
study's words — :class:`study_server.trials.lists.TooManyLists`, :class:`study_server.trials.ingest.Conflict`,
:class:`study_server.participants.flow.NotCurrentTrial`, … — with a message a person can act on and the input ``field``
it is about. Each class says once, as ``status``, what it means to a client (409 a state the request does not fit,
410 a session that has ended, 429 a quota, 503 something the server lacks just now); services never build HTTP
answers. Routes raise :class:`RequestError` (a StudyError whose status is given) for what they parse themselves,
and turn the engine's :class:`scenesuggest.errors.SceneSuggestError` and
:class:`scenesuggest.contract.events.EventError` into it where a request carries engine input. ``create_app`` answers
every StudyError in one place (:func:`answer`): ``{"error": message, "field": name, …}`` as JSON under ``/api/``
and for JSON requests (the admin's scene editor), the calm message page everywhere else; what the request had
changed is rolled back. A route catches a StudyError only to show a page of its own; what a refusal records, the
service records (and commits) before it raises.

The same place answers HTTP errors and unexpected failures (never a stack trace; participant pages get a reference
that is in the session log). A database that cannot store anything right now (read-only, full, locked or
unreachable) is no bug to hide behind a 500: the API answers 503 with ``Retry-After`` (the browser's outbox keeps
the events and sends them again) and participant pages say that the work is kept and to wait a moment.
"""

from __future__ import annotations

from flask_babel import gettext as _
from sqlalchemy.exc import DBAPIError

RETRY_AFTER_S = 5
UNAVAILABLE = "the study's database cannot store data right now; nothing was stored — please send again shortly"
_UNAVAILABLE_MARKERS = ("readonly database", "read-only", "read only", "disk is full", "database or disk is full",
                        "no space left", "could not extend", "database is locked", "unable to open database",
                        "could not connect", "server closed the connection", "connection refused")


class StudyError(Exception):
    """What a service could not do, and why: ``message``, the ``field`` it is about, extra response ``headers``
    (e.g. Retry-After) and ``extra`` keys for the JSON answer; ``status`` (class attribute) is what it means to a
    client."""

    status = 409

    def __init__(self, message: str, field: str | None = None, headers: dict | None = None,
                 extra: dict | None = None):
        super().__init__(message)
        self.message, self.field = message, field
        self.headers, self.extra = headers or {}, extra or {}


class RequestError(StudyError):
    """A request a route cannot apply, with its ``status`` (4xx) given where it is raised."""

    def __init__(self, status: int, message: str, field: str | None = None, headers: dict | None = None,
                 extra: dict | None = None):
        super().__init__(message, field, headers, extra)
        self.status = status


def answer(e: StudyError):
    """The response for ``e``: JSON for the API and JSON requests, the calm page otherwise; nothing the request
    changed is kept."""
    from flask import jsonify

    from .extensions import db

    db.session.rollback()
    if _is_api():
        return jsonify({"error": e.message, "field": e.field, **e.extra}), e.status, e.headers
    return (*_page(e.status, e.message), e.headers)


def _is_api() -> bool:
    from flask import request

    return request.path.startswith("/api/") or request.is_json


def _page(status: int, message: str, reference: str | None = None):
    from flask import render_template

    return render_template("message.html", title=_("Sorry"), message=message, reference=reference, study=None), status


def _log_participant_failure(status: int, e: BaseException) -> str | None:
    """On a participant page, a session-log row the participant can quote (its reference is on the page)."""
    import secrets

    from flask import request

    from .extensions import db
    from .models import log

    if not request.path.startswith("/study/"):
        return None
    reference = secrets.token_hex(4)
    try:
        log("error", None, study_id=(request.view_args or {}).get("study_id"), reference=reference,
            path=request.path, status=status, error=type(e).__name__)
        db.session.commit()
    except Exception:  # the database itself may be what failed
        db.session.rollback()
    return reference


def http_error(e):
    """Werkzeug's HTTP errors (unknown URLs, wrong methods, aborts): JSON for the API, a calm page elsewhere."""
    from flask import current_app, jsonify
    from werkzeug.exceptions import SecurityError

    from .extensions import db

    if isinstance(e, SecurityError):  # a Host the server does not answer for: no page of ours names it
        return current_app.response_class("This server does not answer for that host name.\n", 400,
                                          mimetype="text/plain")
    if _is_api():
        limit = current_app.config.get("MAX_CONTENT_LENGTH")
        if e.code == 413 and limit:  # the body is over MAX_CONTENT_LENGTH: say which limit
            return jsonify({"error": f"the request body is larger than the {limit} bytes a request may carry",
                            "field": "body"}), 413
        return jsonify({"error": e.description or e.name, "field": None}), e.code
    db.session.rollback()
    message = e.description if e.code == 400 else (
        _("This page does not exist. Please use the link you were given.") if e.code in (404, 405)
        else _("This request cannot be answered (%(status)s). Please go back and try again.", status=e.code))
    return _page(e.code, message, _log_participant_failure(e.code, e))


def unexpected(e: Exception):
    """A failure nobody meant: logged, answered without a stack trace. A database that cannot store anything
    right now is a 503 (the API adds Retry-After; the outbox sends again), anything else a 500."""
    from flask import current_app, jsonify

    from .extensions import db

    db.session.rollback()
    if database_unavailable(e):
        current_app.logger.error("database unavailable: %s", e)
        if _is_api():
            return jsonify({"error": UNAVAILABLE, "field": None}), 503, {"Retry-After": str(RETRY_AFTER_S)}
        return _page(503, _("We cannot save anything for a moment. Your work is kept in this browser; please wait "
                            "a minute and reload this page."), _log_participant_failure(503, e))
    current_app.logger.exception("request failure")
    if _is_api():
        return jsonify({"error": "internal error; the request was not applied", "field": None}), 500
    return _page(500, _("Something went wrong on our side. Your work is saved; please reload this page in a "
                        "moment."), _log_participant_failure(500, e))


def database_unavailable(error: BaseException) -> bool:
    """Whether ``error`` says the database cannot store data at the moment (as opposed to a bug)."""
    if not isinstance(error, DBAPIError):
        return False
    text = str(error.orig if error.orig is not None else error).lower()
    return bool(error.connection_invalidated) or any(m in text for m in _UNAVAILABLE_MARKERS)
