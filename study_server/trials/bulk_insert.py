"""The SQL of storing an event batch, driver by driver: the insert-or-ignore of its events, compiled once per
database and fed column by column (:func:`insert_events`), and the one UPDATE of the participant's counters that
follows it (:data:`COUNT`). :mod:`study_server.trials.ingest` says what a batch means; this module only how it is
written fast."""

from __future__ import annotations

import functools

from sqlalchemy import BigInteger, Integer, bindparam, case, update
from sqlalchemy.exc import DBAPIError

from ..base.extensions import db, insert_ignore
from ..base.models import Event, Participant

#: The events columns an insert writes: those the whole batch shares …
BATCH_COLUMNS = ("participant_id", "page_id", "server_t", "vocabulary")
#: … and each event's own, with the key of the (validated) event that gives it.
EVENT_FIELDS = {"seq": "seq", "type": "type", "trial": "trial", "client_t": "t", "payload": "payload"}
#: All of them, as the insert names them.
INSERT_COLUMNS = (*BATCH_COLUMNS, *EVENT_FIELDS)


def insert_events(common: dict, batch: list[dict]) -> int:
    """Insert the events of ``batch`` (validated) that are new, with the ``common`` values of
    :data:`BATCH_COLUMNS`; returns how many were new. The insert is compiled once per database and its parameters
    made by the columns' own bind processors (what SQLAlchemy would send; a shared value processed once), one
    column at a time, straight to the driver: a general execute's per-row work was a third of the insert's CPU.
    SQLite: one executemany, whose row count is the rows inserted. PostgreSQL (psycopg): one statement of column
    arrays (:func:`_unnest_insert`), whose returned rows are those inserted."""
    connection = db.session.connection()
    dialect = connection.dialect
    if dialect.name != "sqlite" and dialect.driver != "psycopg":  # another driver: SQLAlchemy's own insert
        statement = insert_ignore(Event.__table__, ["participant_id", "seq"]).returning(Event.__table__.c.seq)
        rows = [common | {c: e[k] for c, k in EVENT_FIELDS.items()} for e in batch]
        return len(db.session.execute(statement, rows).all())
    sql, columns = (_sqlite_insert if dialect.name == "sqlite" else _unnest_insert)(dialect)
    arrays = [_column(common, batch, c, p) for c, p in columns]
    if dialect.name == "sqlite":
        return connection.exec_driver_sql(sql, list(zip(*arrays, strict=True))).rowcount
    try:
        with connection.connection.dbapi_connection.cursor() as cursor:  # in the session's transaction
            cursor.execute(sql, arrays)
            return len(cursor.fetchall())
    except dialect.loaded_dbapi.Error as e:  # as SQLAlchemy would raise it: a lost database answers 503
        raise DBAPIError.instance(sql, None, e, dialect.loaded_dbapi.Error,
                                  connection_invalidated=dialect.is_disconnect(e, None, None)) from e


def _column(common: dict, batch: list[dict], column: str, process) -> list:
    """Column ``column``'s values for the events of ``batch``, through its bind processor ``process`` (or None)."""
    if column in common:
        value = common[column]
        return [value if process is None else process(value)] * len(batch)
    key = EVENT_FIELDS[column]
    return [e[key] for e in batch] if process is None else [process(e[key]) for e in batch]


def _bind_processors(dialect, names) -> tuple:
    """(column, its bind processor for ``dialect``) for each of ``names``."""
    table = Event.__table__
    return tuple((n, table.c[n].type.dialect_impl(dialect).bind_processor(dialect)) for n in names)


@functools.lru_cache(maxsize=8)
def _unnest_insert(dialect) -> tuple[str, tuple]:
    """PostgreSQL's events insert-or-ignore as one statement whatever the batch: each column's values as one array,
    ``INSERT … SELECT FROM unnest(…) ON CONFLICT DO NOTHING RETURNING seq`` (one parse, one round trip; the rows
    returned are those that were new). The arrays go in PostgreSQL's binary format (``%b``): as text, every
    payload's quotes were escaped one by one, a third of the request's CPU. Its SQL and, in parameter order,
    (column, bind processor)."""
    table = Event.__table__
    arrays = ", ".join(f"%b::{table.c[n].type.compile(dialect=dialect)}[]" for n in INSERT_COLUMNS)
    sql = (f"INSERT INTO {table.name} ({', '.join(INSERT_COLUMNS)}) SELECT * FROM unnest({arrays}) "
           f"ON CONFLICT (participant_id, seq) DO NOTHING RETURNING seq")
    return sql, _bind_processors(dialect, INSERT_COLUMNS)


@functools.lru_cache(maxsize=8)
def _sqlite_insert(dialect) -> tuple[str, tuple]:
    """The events insert-or-ignore compiled for SQLite: its SQL and, in parameter order, (column, bind processor)."""
    from sqlalchemy.dialects.sqlite import insert

    statement = insert(Event.__table__).values({n: bindparam(n) for n in INSERT_COLUMNS})
    compiled = statement.on_conflict_do_nothing(index_elements=["participant_id", "seq"]).compile(dialect=dialect)
    return compiled.string, _bind_processors(dialect, compiled.positiontup)


def count_statement(quota: bool):
    """The one UPDATE of a stored batch: acked seq, event and byte counters, last seen (and the quota check); it
    returns the row's acked seq and event count as they now are (no row: over quota)."""
    p = Participant.__table__.c
    n, size, acked = bindparam("n", type_=Integer), bindparam("size", type_=BigInteger), bindparam("acked", Integer)
    statement = update(Participant.__table__).where(p.id == bindparam("pid"))
    if quota:
        statement = statement.where(p.events_stored + n <= bindparam("max_events", type_=Integer),
                                    p.bytes_stored + size <= bindparam("max_bytes", type_=BigInteger))
    return statement.values(acked_seq=case((p.acked_seq < acked, acked), else_=p.acked_seq),
                            events_stored=p.events_stored + n, bytes_stored=p.bytes_stored + size,
                            last_seen_at=bindparam("now")).returning(p.acked_seq, p.events_stored)


#: The batch's UPDATE without and with the quota check.
COUNT, COUNT_WITH_QUOTA = count_statement(False), count_statement(True)
