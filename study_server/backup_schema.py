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
from pathlib import Path

from sqlalchemy.exc import SQLAlchemyError

from .backup_archive import BackupError
from .config import MIGRATIONS

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

    from .extensions import db, migrate

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


def sqlite_objects(path: Path) -> dict[str, tuple[str, str, str]]:
    """Every schema object of the SQLite file ``path`` (name → type, table, SQL with its spaces collapsed), but
    SQLite's own bookkeeping tables (:data:`SQLITE_OWN`)."""
    con = sqlite3.connect(f"{path.resolve().as_uri()}?mode=ro", uri=True)
    try:
        rows = con.execute("SELECT type, name, tbl_name, sql FROM sqlite_master").fetchall()
    finally:
        con.close()
    return {name: (kind, table, " ".join((sql or "").split())) for kind, name, table, sql in rows
            if not (kind == "table" and name in SQLITE_OWN)}


def sqlite_differences(backup: dict, reference: dict) -> list[str]:
    """What ``backup``'s schema has that ``reference``'s (the migrations') has not, or has otherwise."""
    found = []
    for name, (kind, table, sql) in sorted(backup.items()):
        if name not in reference:
            found.append(f"{kind} {name!r}" + (f" on {table}" if table != name else "") + " (not made by the "
                         "migrations)")
        elif reference[name] != (kind, table, sql):
            found.append(f"{kind} {name!r} is not as the migrations create it")
    found += [f"{kind} {name!r} is missing" for name, (kind, _t, _s) in sorted(reference.items())
              if name not in backup]
    return found


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
