"""Recognising a database that cannot store anything right now: read-only, full, locked or unreachable.

Such failures are not bugs to hide behind a 500: the API answers 503 with ``Retry-After`` (the browser's outbox
keeps the events and sends them again), participant pages say that the work is kept and to wait a moment.
"""

from __future__ import annotations

from sqlalchemy.exc import DBAPIError

RETRY_AFTER_S = 5
MESSAGE = "the study's database cannot store data right now; nothing was stored — please send again shortly"
_MARKERS = ("readonly database", "read-only", "read only", "disk is full", "database or disk is full",
            "no space left", "could not extend", "database is locked", "unable to open database",
            "could not connect", "server closed the connection", "connection refused")


def unavailable(error: BaseException) -> bool:
    """Whether ``error`` says the database cannot store data at the moment (as opposed to a bug)."""
    if not isinstance(error, DBAPIError):
        return False
    text = str(error.orig if error.orig is not None else error).lower()
    return bool(error.connection_invalidated) or any(m in text for m in _MARKERS)
