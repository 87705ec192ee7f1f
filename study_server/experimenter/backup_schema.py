"""What a restored database may hold: exactly the schema our migrations create, at the backup's revision.

A backup is code for the database that restores it: a SQLite file can carry triggers (every new participant's
token set to a known string, an exclusion that undoes itself), a ``pg_dump`` archive can carry functions that run
as whoever restores them. So the restore compares what the backup brings with a reference the migrations build
in a scratch database (SQLite: every ``sqlite_master`` row, its SQL included; PostgreSQL: every entry of the
archive's table of contents) and refuses, naming each, anything the migrations do not create.
"""

from __future__ import annotations

import re
import sqlite3
import subprocess
from collections import Counter
from pathlib import Path

from sqlalchemy.exc import SQLAlchemyError

from ..base.config import MIGRATIONS
from .backup_archive import BackupError

#: Tables whose rows are sign-ins, not study data: never carried across a restore.
SIGN_INS = ("login_attempts", "admin_sessions", "admin_links")


def known_revisions() -> set[str]:
    from alembic.config import Config
    from alembic.script import ScriptDirectory

    config = Config()
    config.set_main_option("script_location", str(MIGRATIONS))
    return {script.revision for script in ScriptDirectory.from_config(config).walk_revisions()}


def migrate_to(url: str, revision: str) -> None:
    """Build the schema of ``revision`` in the database at ``url`` with our migrations (a bare app: no studies,
    no secrets)."""
    import logging

    from flask import Flask
    from flask_migrate import upgrade

    from ..base.extensions import db, migrate

    app = Flask("scenesuggest-restore")
    app.config["SQLALCHEMY_DATABASE_URI"] = url
    db.init_app(app)
    migrate.init_app(app, db, directory=str(MIGRATIONS))
    root = logging.getLogger()
    silent = logging.NullHandler()  # env.py sets up alembic's chatty logging only when nothing is set up
    root.addHandler(silent)
    try:
        with app.app_context():
            try:
                upgrade(directory=str(MIGRATIONS), revision=revision)
            except SQLAlchemyError as e:
                raise BackupError(f"cannot build the schema there ({type(e).__name__}: "
                                  f"{str(e).splitlines()[0]}); does the role own the database?", field="--db"
                                  ) from None
            finally:
                db.engine.dispose()
    finally:
        root.removeHandler(silent)


# --- SQLite ------------------------------------------------------------------------------------------------------
#: SQLite's own bookkeeping tables (ANALYZE's statistics, AUTOINCREMENT's counters): the only schema rows a
#: database may hold that the migrations do not make. Anything else named ``sqlite_…`` (a trigger, say) is not.
SQLITE_OWN = ("sqlite_sequence", "sqlite_stat1", "sqlite_stat4")


def sqlite_objects(path: Path) -> list[tuple[str, str, str, str]]:
    """Every schema object of the SQLite file ``path`` as (type, name, table, SQL with its spaces collapsed), one
    entry per ``sqlite_master`` row (SQLite keeps triggers in a namespace of their own, so a name may come twice),
    but SQLite's own bookkeeping tables (:data:`SQLITE_OWN`)."""
    con = sqlite3.connect(f"{path.resolve().as_uri()}?mode=ro", uri=True)
    try:
        rows = con.execute("SELECT type, name, tbl_name, sql FROM sqlite_master").fetchall()
    finally:
        con.close()
    return [(kind, name, table, " ".join((sql or "").split())) for kind, name, table, sql in rows
            if not (kind == "table" and name in SQLITE_OWN)]


def sqlite_differences(backup: list, reference: list) -> list[str]:
    """What ``backup``'s schema objects (:func:`sqlite_objects`) have that ``reference``'s (the migrations') have
    not, or have otherwise, counting every object: each must be one of the migrations', as many times."""
    extra, missing = Counter(backup) - Counter(reference), Counter(reference) - Counter(backup)
    changed = {(k, n) for k, n, _t, _s in extra} & {(k, n) for k, n, _t, _s in missing}
    ours = {name for _k, name, _t, _s in reference}
    found = []
    for kind, name, table, _sql in sorted(extra.elements()):
        on = f" on {table}" if table != name else ""
        if (kind, name) in changed:
            found.append(f"{kind} {name!r} is not as the migrations create it")
        elif name in ours:  # SQLite keeps triggers apart: a trigger may take the name of an index of ours
            found.append(f"{kind} {name!r}{on}, named like an object of the migrations (not made by them)")
        else:
            found.append(f"{kind} {name!r}{on} (not made by the migrations)")
    found += [f"{kind} {name!r} is missing" for kind, name, _t, _s in sorted(missing.elements())
              if (kind, name) not in changed]
    return list(dict.fromkeys(found))


#: The largest row id a restore accepts: a billion rows, more than any study writes, so that an id sequence carried
#: across has at least a billion arrivals left (PostgreSQL's ``integer`` ids end at 2³¹ − 1).
ID_LIMIT = 2**30
_DATE = "[0-9][0-9][0-9][0-9]-[0-9][0-9]-[0-9][0-9] [0-9][0-9]:[0-9][0-9]:[0-9][0-9]"


def _written_by_app(declared: str, column: str, nullable: bool, key: bool) -> str:
    """A SQL condition that is true (never NULL) of every value the app can write into a SQLite column of the
    ``declared`` type (as SQLAlchemy stores it): integers as integers (a primary key from 1 to ID_LIMIT), times as
    ``YYYY-MM-DD HH:MM:SS[.ffffff]`` naming a real instant from year 1 on, JSON as valid JSON text, strings as text
    within their length; no text with a NUL (SQLite's own functions stop reading at one)."""
    c = '"' + column.replace('"', '""') + '"'
    kind = declared.upper()
    length = re.fullmatch(r"VARCHAR\((\d+)\)", kind)
    text = f"typeof({c}) = 'text' AND instr({c}, char(0)) = 0"
    if kind in ("INTEGER", "BIGINT", "SMALLINT"):
        check = f"typeof({c}) = 'integer'" + (f" AND {c} BETWEEN 1 AND {ID_LIMIT}" if key else "")
    elif kind == "BOOLEAN":
        check = f"typeof({c}) = 'integer' AND {c} IN (0, 1)"
    elif kind == "FLOAT":
        check = f"typeof({c}) IN ('real', 'integer')"
    elif kind == "DATETIME":  # a day and a time that exist: 2026-02-31 moved by no days is 3 March
        check = (f"{text} AND ({c} GLOB '{_DATE}' OR {c} GLOB '{_DATE}.[0-9][0-9][0-9][0-9][0-9][0-9]')"
                 f" AND substr({c}, 1, 4) <> '0000'"
                 f" AND date(substr({c}, 1, 10), '+0 days') = substr({c}, 1, 10)"
                 f" AND time(substr({c}, 12, 8)) = substr({c}, 12, 8)")
    elif kind == "JSON":
        check = f"{text} AND json_valid({c})"
    elif length:
        check = f"{text} AND length({c}) <= {length.group(1)}"
    elif kind == "TEXT":
        check = text
    else:
        raise ValueError(f"no rule for the SQLite type {declared!r} of column {column!r}")
    return f"COALESCE({c} IS NULL OR ({check}), 0)" if nullable else f"COALESCE({c} IS NOT NULL AND {check}, 0)"


def sqlite_value_problems(con: sqlite3.Connection, schema: str, skip: tuple[str, ...]) -> list[str]:
    """The columns of the tables (but ``skip``) of the database attached to ``con`` as ``schema`` that hold values
    the app cannot have written (see :func:`_written_by_app`; the types are those of ``con``'s main database, the
    migrations'), and the rows whose foreign keys name no row: each with how many and the first row's id."""
    found = []
    tables = _tables(con, skip)
    for table in tables:
        columns = con.execute(f'PRAGMA main.table_info("{table}")').fetchall()  # cid, name, type, notnull, _, pk
        checks = [_written_by_app(kind, name, not notnull and not pk, pk == 1 and name == "id")
                  for _cid, name, kind, notnull, _default, pk in columns]
        bad = con.execute("SELECT " + ", ".join(f"COALESCE(SUM(NOT {c}), 0)" for c in checks)
                          + f' FROM {schema}."{table}"').fetchone()
        for (_cid, name, _kind, *_rest), check, count in zip(columns, checks, bad, strict=True):
            if count:
                first = con.execute(f'SELECT rowid, quote(substr("{name}", 1, 41)) FROM {schema}."{table}" '
                                    f"WHERE NOT {check} ORDER BY rowid LIMIT 1").fetchone()
                shown = first[1] if len(first[1]) <= 40 else first[1][:40] + "…"
                found.append(f"{table}.{name}: {count} value{'s' * (count > 1)} the app cannot have written "
                             f"(the first in row {first[0]}: {shown})")
    dangling = con.execute(f"PRAGMA {schema}.foreign_key_check").fetchall()  # table, rowid, parent, fk index
    for (table, parent), rows in _grouped(dangling).items():
        if table in skip:
            continue
        found.append(f"{table}: {len(rows)} row{'s' * (len(rows) > 1)} naming a {parent} row that does not exist "
                     f"(the first: row {min(rows)})")
    return found


def _tables(con: sqlite3.Connection, skip: tuple[str, ...]) -> list[str]:
    """The tables of ``con``'s main database (the migrations'), but SQLite's own and ``skip``."""
    return [name for (name,) in con.execute("SELECT name FROM main.sqlite_master WHERE type = 'table' AND "
                                            "name NOT LIKE 'sqlite_%' ORDER BY name") if name not in skip]


def _grouped(dangling: list) -> dict:
    out: dict = {}
    for table, rowid, parent, _index in dangling:
        out.setdefault((table, parent), []).append(rowid)
    return out


def copy_sqlite_rows(con: sqlite3.Connection, schema: str, skip: tuple[str, ...]) -> None:
    """Copy every row of the tables of ``con``'s main database (the migrations' schema) from the database attached
    as ``schema``, in one transaction, but the tables of ``skip``: the migrations made every table, index and
    trigger, and nothing of the backup's schema comes across."""
    with con:
        for table in _tables(con, skip):
            names = ", ".join('"' + c[1].replace('"', '""') + '"'
                              for c in con.execute(f'PRAGMA main.table_info("{table}")'))
            con.execute(f'INSERT INTO main."{table}" ({names}) SELECT {names} FROM {schema}."{table}" '  # noqa: S608
                        "ORDER BY rowid")


def check_sqlite_head(head: bytes, size: int) -> None:
    """Refuse a SQLite payload whose header does not describe a database of exactly ``size`` bytes (a forged
    page count), from its first bytes."""
    if len(head) < 100 or not head.startswith(b"SQLite format 3\x00"):
        raise BackupError("the backup's database is not a SQLite file")
    page = int.from_bytes(head[16:18], "big")
    page = 65536 if page == 1 else page
    pages = int.from_bytes(head[28:32], "big")
    if head[24:28] != head[92:96] or page < 512 or page & (page - 1) or pages * page != size:
        raise BackupError(f"the backup's SQLite header says {pages} pages of {page} bytes, but it holds {size} "
                          "bytes: not a file SQLite wrote")


# --- PostgreSQL ---------------------------------------------------------------------------------------------------
#: What a table of contents of our schema holds: rows, tables and what hangs on them. Anything else (FUNCTION,
#: TRIGGER, VIEW, RULE, POLICY, EXTENSION, EVENT TRIGGER, TYPE, …) is refused.
SCHEMA_ENTRIES = ("TABLE", "SEQUENCE", "SEQUENCE OWNED BY", "DEFAULT", "CONSTRAINT", "FK CONSTRAINT", "INDEX")
DATA_ENTRIES = ("TABLE DATA", "SEQUENCE SET")
_ENTRY = re.compile(r"^(\d+); (\d+) (\d+) (.*)$")


def pg_toc(pg_restore: str, archive: Path) -> list[tuple[str, str, str, str]]:
    """The table of contents of a ``pg_dump`` archive: (line, kind, schema, name) for each entry."""
    done = subprocess.run([pg_restore, "--list", str(archive)], capture_output=True, text=True)
    if done.returncode:
        last = (done.stderr.strip().splitlines() or ["no message"])[-1]
        raise BackupError(f"pg_restore cannot read the archive: {last}")
    entries = []
    for line in done.stdout.splitlines():
        match = _ENTRY.match(line)
        if not match:
            continue
        rest = match.group(4)
        kind = next((k for k in sorted(SCHEMA_ENTRIES + DATA_ENTRIES, key=len, reverse=True)
                     if rest.startswith(k + " ")), None)
        if kind is None:
            entries.append((line, rest.split(" ", 1)[0], "", rest))
            continue
        words = rest[len(kind) + 1:].split(" ")
        schema, name = words[0], " ".join(words[1:-1])  # the last word is the owner
        entries.append((line, kind, schema, name))
    return entries


def pg_schema(entries) -> set[tuple[str, str, str]]:
    return {(kind, schema, name) for _line, kind, schema, name in entries if kind in SCHEMA_ENTRIES}


def pg_refusals(entries, reference: set[tuple[str, str, str]] | None) -> list[str]:
    """The archive's entries our migrations do not make: every kind of entry but tables, rows and what hangs on
    tables; and, given the ``reference`` schema (the migrations', dumped), any table, index, constraint or
    sequence not in it."""
    found = []
    for line, kind, schema, name in entries:
        if kind not in SCHEMA_ENTRIES + DATA_ENTRIES:
            found.append(f"{line.split(' ', 3)[3]} (not made by the migrations)")
        elif schema != "public":
            found.append(f"{kind} {schema}.{name} (outside the public schema)")
        elif reference is not None and kind in SCHEMA_ENTRIES and (kind, schema, name) not in reference:
            found.append(f"{kind} {name} (not made by the migrations)")
    return found
