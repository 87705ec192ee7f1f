"""Backups that restore: ``scenesuggest study backup`` and ``study restore``.

SQLite is copied with its online backup API (one read transaction: a consistent snapshot while participants
keep writing); PostgreSQL with ``pg_dump`` in its custom format (a snapshot too), restored by ``pg_restore`` in one
transaction. A backup is written beside its name and linked into place, so it never replaces a file; a restore
goes only into an empty database (no tables), so it never mixes two studies' data. Both say what they hold: the
schema revision and the number of participants and events.
"""

from __future__ import annotations

import glob
import os
import shutil
import sqlite3
import subprocess
from pathlib import Path

from sqlalchemy import create_engine, inspect, text
from sqlalchemy.engine import URL, make_url
from sqlalchemy.exc import SQLAlchemyError

from scenesuggest.errors import SceneSuggestError

SQLITE_MAGIC = b"SQLite format 3\x00"
PG_MAGIC = b"PGDMP"
#: The tables every database of this app has: a backup without them is not one of ours.
OURS = ("alembic_version", "participants", "events", "trials")


class BackupError(SceneSuggestError):
    pass


def _kind(url: str) -> str:
    try:
        name = make_url(url).get_backend_name()
    except Exception:  # noqa: BLE001 - any unparsable URL
        raise BackupError("not a database URL", field="--db") from None
    if name not in ("sqlite", "postgresql"):
        raise BackupError(f"{name} databases are not supported (SQLite or PostgreSQL)", field="--db")
    return name


def _counts(con) -> dict:
    """The schema revision and row counts of a database of this app (on an open connection)."""
    missing = [t for t in OURS if not inspect(con).has_table(t)]
    if missing:
        raise BackupError(f"not a database of this app (no {', '.join(missing)} table)")
    return {"revision": con.execute(text("SELECT version_num FROM alembic_version")).scalar(),
            "participants": con.execute(text("SELECT COUNT(*) FROM participants")).scalar(),
            "events": con.execute(text("SELECT COUNT(*) FROM events")).scalar()}


def _summary(url: str) -> dict:
    engine = create_engine(url)
    try:
        with engine.connect() as con:
            return _counts(con)
    finally:
        engine.dispose()


def _tables(url: str) -> list[str]:
    engine = create_engine(url)
    try:
        with engine.connect() as con:
            return inspect(con).get_table_names()
    except SQLAlchemyError as e:
        raise BackupError(f"cannot open the database ({type(e).__name__}: {str(e).splitlines()[0]})",
                          field="--db") from None
    finally:
        engine.dispose()


def _sqlite_path(url: str) -> Path:
    name = make_url(url).database
    if not name or name == ":memory:" or name.startswith("file:"):
        raise BackupError("expected a SQLite database file", field="--db")
    return Path(name)


def _pg_tool(name: str) -> str:
    versions = sorted(glob.glob(f"/usr/lib/postgresql/*/bin/{name}"), key=lambda p: int(p.split("/")[4].split(".")[0])
                      if p.split("/")[4].split(".")[0].isdigit() else 0)
    found = shutil.which(name) or (versions[-1] if versions else None)
    if not found:
        raise BackupError(f"{name} is not installed (apt-get install postgresql-client)")
    return found


def _libpq(url: str) -> tuple[str, dict]:
    """A libpq connection URI for ``url`` (without its password, which goes in the environment) and that
    environment."""
    u = make_url(url)
    plain = URL.create("postgresql", u.username, None, u.host, u.port, u.database, u.query)
    env = {**os.environ} | ({"PGPASSWORD": u.password} if u.password else {})
    return plain.render_as_string(hide_password=False), env


def _run(command: list[str], env: dict, what: str) -> None:
    done = subprocess.run(command, env=env, capture_output=True, text=True)
    if done.returncode:
        last = (done.stderr.strip().splitlines() or ["no message"])[-1]
        raise BackupError(f"{what} failed: {last}")


def _private_file(path: Path) -> None:
    """Create ``path`` (new) readable by its owner only: a backup holds what the database holds."""
    os.close(os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600))


def _claim(out: Path) -> Path:
    """A new, private temporary file beside ``out`` to write the backup into, after checking ``out`` is free."""
    if out.exists():
        raise BackupError("exists: a backup never replaces a file (choose another name)", file=str(out))
    tmp = out.with_name(f".{out.name}.{os.getpid()}.partial")
    try:
        out.parent.mkdir(parents=True, exist_ok=True)
        tmp.unlink(missing_ok=True)
        _private_file(tmp)
    except OSError as e:
        raise BackupError(f"cannot write there: {e.strerror}", file=str(out)) from None
    return tmp


def _pg_dump(url: str, tmp: Path) -> dict:
    """``pg_dump`` of the snapshot a repeatable-read transaction exports, counted in that same snapshot, so the
    summary describes exactly what the dump holds."""
    engine = create_engine(url, isolation_level="REPEATABLE READ")
    try:
        with engine.connect() as con:
            snapshot = con.execute(text("SELECT pg_export_snapshot()")).scalar()
            summary = _counts(con)
            uri, env = _libpq(url)
            _run([_pg_tool("pg_dump"), "--format=custom", "--no-owner", "--no-password", f"--snapshot={snapshot}",
                  f"--file={tmp}", f"--dbname={uri}"], env, "pg_dump")
            return summary
    except SQLAlchemyError as e:
        raise BackupError(f"cannot read the database ({type(e).__name__}: {str(e).splitlines()[0]})",
                          field="--db") from None
    finally:
        engine.dispose()


def backup(url: str, out: str | Path) -> dict:
    """Back up the database at ``url`` into the new file ``out``; returns what it holds (kind, revision,
    participants, events, bytes)."""
    out = Path(out)
    kind = _kind(url)
    if kind == "sqlite" and not _sqlite_path(url).is_file():
        raise BackupError("no such database file", field="--db")
    tmp = _claim(out)
    summary = None
    try:
        if kind == "sqlite":
            source = sqlite3.connect(f"{_sqlite_path(url).resolve().as_uri()}?mode=ro", uri=True, timeout=30)
            target = sqlite3.connect(tmp)
            try:
                source.backup(target)  # one read transaction: a snapshot of committed data
                target.execute("PRAGMA journal_mode=DELETE")  # one self-contained file, whatever the server used
            finally:
                target.close()
                source.close()
            summary = _summary(f"sqlite:///{tmp}")
        else:
            summary = _pg_dump(url, tmp)
        os.link(tmp, out)  # fails rather than replace a file made meanwhile
    except FileExistsError:
        raise BackupError("exists: a backup never replaces a file (choose another name)", file=str(out)) from None
    finally:
        tmp.unlink(missing_ok=True)
    return {"kind": kind, **summary, "bytes": out.stat().st_size}


def restore(source: str | Path, url: str) -> dict:
    """Restore the backup ``source`` into the empty database at ``url``; returns what it holds and the result
    of the database's integrity check."""
    source = Path(source)
    try:
        with source.open("rb") as f:
            head = f.read(16)
    except OSError as e:
        raise BackupError(f"cannot read: {e.strerror}", file=str(source)) from None
    made_by = "sqlite" if head == SQLITE_MAGIC else "postgresql" if head.startswith(PG_MAGIC) else None
    if made_by is None:
        raise BackupError("not a backup (neither a SQLite database nor a pg_dump archive)", file=str(source))
    kind = _kind(url)
    if made_by != kind:
        raise BackupError(f"a {made_by} backup restores into {made_by}, not into this {kind} database",
                          field="--db")
    if kind == "sqlite":
        path = _sqlite_path(url)
        if path.exists() and path.stat().st_size and _tables(url):
            raise BackupError("the database is not empty: restore into a new one (a restore never mixes data)",
                              field="--db")
        _summary(f"sqlite:///{source}")  # one of ours, before anything is written
        if not path.exists():
            path.parent.mkdir(parents=True, exist_ok=True)
            _private_file(path)
        backup_db = sqlite3.connect(f"{source.resolve().as_uri()}?mode=ro", uri=True)
        target = sqlite3.connect(path)
        try:
            backup_db.backup(target)
            check = target.execute("PRAGMA integrity_check").fetchone()[0]
        finally:
            target.close()
            backup_db.close()
        if check != "ok":
            path.unlink()
            raise BackupError(f"the restored database fails SQLite's integrity check ({check}); nothing was kept",
                              file=str(source))
    else:
        if _tables(url):
            raise BackupError("the database is not empty: restore into a new one (a restore never mixes data)",
                              field="--db")
        uri, env = _libpq(url)
        _run([_pg_tool("pg_restore"), "--no-owner", "--no-privileges", "--no-password", "--exit-on-error",
              "--single-transaction",
              f"--dbname={uri}", str(source)], env, "pg_restore")
        check = "ok"  # pg_restore checked every statement in one transaction
    return {"kind": kind, **_summary(url), "integrity": check}
