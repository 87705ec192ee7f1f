"""URL converters: a number in a path is one both databases can hold, else the page does not exist (404)."""

from __future__ import annotations

from werkzeug.routing import IntegerConverter

#: PostgreSQL's ``integer`` (and SQLite's bound parameters, which stop at 2⁶³): the widest id a row has.
INT32 = 2**31 - 1


class RowNumber(IntegerConverter):
    """``<row:pid>``, ``<row(signed=True):index>``: an integer within 32 bits. A larger one would reach the
    database as an overflow (a 500 on SQLite beyond 2⁶³, on PostgreSQL beyond 2³¹); it is a 404 here."""

    def __init__(self, map, signed: bool = False) -> None:  # noqa: A002 - werkzeug's name
        super().__init__(map, signed=signed, min=-INT32 - 1 if signed else 0, max=INT32)
