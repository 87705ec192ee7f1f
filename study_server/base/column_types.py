"""Column types that read a stored value the app cannot have written as None, not as an error.

The database holds only what the app writes, and a restore refuses anything else (``backup_schema``). Should a
cell be changed behind the app's back all the same (a time that is no time, JSON that is not JSON), the row reads
with None there and a warning names the column, so that one bad row cannot take down every admin page and the
export; the pages show the value as missing.
"""

from __future__ import annotations

import logging

from sqlalchemy import JSON, DateTime, TypeDecorator

log = logging.getLogger(__name__)


def _tolerant(name: str, inner):
    if inner is None:
        return None

    def process(value):
        try:
            return inner(value)
        except (ValueError, TypeError, RecursionError):  # JSONDecodeErrors are ValueErrors
            log.warning("a %s column holds a value the app cannot have written (%.40r): read as missing", name, value)
            return None
    return process


class Time(TypeDecorator):
    """:class:`sqlalchemy.DateTime` (naive UTC); a stored text that names no instant reads as None."""

    impl = DateTime
    cache_ok = True

    def result_processor(self, dialect, coltype):
        return _tolerant("time", super().result_processor(dialect, coltype))


class Document(TypeDecorator):
    """:class:`sqlalchemy.JSON`; a stored text that is not JSON reads as None."""

    impl = JSON
    cache_ok = True

    def result_processor(self, dialect, coltype):
        return _tolerant("JSON", super().result_processor(dialect, coltype))
