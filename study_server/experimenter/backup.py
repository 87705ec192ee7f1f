"""Backups that restore: ``scenesuggest study backup`` and ``study restore``.

SQLite is copied with its online backup API (one read transaction: a consistent snapshot while participants
keep writing); PostgreSQL with ``pg_dump`` in its custom format (a snapshot too). Either goes into one file with a
manifest of what made it and the payload's SHA-256 (``backup_archive``). A backup is written beside its name and
linked into place, so it never replaces a file.

A restore goes only into an empty database (no tables), so it never mixes two studies' data, and only restores
what ``study backup`` wrote and our migrations define: the digest must match; the schema the backup brings is
compared, object by object, with the one the migrations build at its revision, and anything else (a trigger, a
view, a function, a changed table) is refused by name (``backup_schema``). Either way the restored schema is the
migrations' own and the backup gives only rows: a SQLite backup's rows are copied into a file the migrations
built (its values checked first: only what the app can have written, ids within ID_LIMIT, foreign keys that name
rows; SQLite's statistics never come across), a PostgreSQL archive's rows are loaded by COPY statements of ours,
as the app's role, never a superuser. Sign-ins (login attempts, admin sessions) are not carried across. Nothing
is expanded beyond the backup's real size on disk before it is checked.
"""

from __future__ import annotations

import glob
import os
import re
import shutil
import sqlite3
import subprocess
import tempfile
from contextlib import contextmanager
from pathlib import Path

from sqlalchemy import MetaData, create_engine, inspect, text
from sqlalchemy.engine import URL, make_url
from sqlalchemy.exc import SQLAlchemyError

import scenesuggest

from .backup_archive import PAYLOAD, BackupError, extract_payload, read_manifest, write_archive
from .backup_schema import (
    ID_LIMIT,
    SIGN_INS,
    check_sqlite_head,
    copy_sqlite_rows,
    known_revisions,
    migrate_to,
    pg_refusals,
    pg_schema,
    pg_toc,
    sqlite_differences,
    sqlite_objects,
    sqlite_value_problems,
)

__all__ = ["BackupError", "backup", "restore"]

#: The tables every database of this app has: a backup without them is not one of ours.
OURS = ("alembic_version", "participants", "events", "trials")


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


@contextmanager
def _connected(url: str, begin: bool = False, doing: str = "open", **engine_options):
    """A connection to the database at ``url`` (in a transaction committed at the end with ``begin``; the engine
    made with ``engine_options``), its engine disposed after; a database error is a :class:`BackupError` naming
    ``--db`` and saying what could not be done (``cannot open the database``)."""
    engine = create_engine(url, **engine_options)
    try:
        with engine.begin() if begin else engine.connect() as con:
            yield con
    except SQLAlchemyError as e:
        raise BackupError(f"cannot {doing} the database ({type(e).__name__}: {str(e).splitlines()[0]})",
                          field="--db") from None
    finally:
        engine.dispose()


def _summary(url: str) -> dict:
    with _connected(url) as con:
        return _counts(con)


def _tables(url: str) -> list[str]:
    with _connected(url) as con:
        return inspect(con).get_table_names()


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
    with _connected(url, doing="read", isolation_level="REPEATABLE READ") as con:
        snapshot = con.execute(text("SELECT pg_export_snapshot()")).scalar()
        summary = _counts(con)
        uri, env = _libpq(url)
        _run([_pg_tool("pg_dump"), "--format=custom", "--no-owner", "--no-privileges", "--no-password",
              f"--snapshot={snapshot}", f"--file={tmp}", f"--dbname={uri}"], env, "pg_dump")
        return summary


def _dump(url: str, kind: str, into: Path) -> dict:
    """Copy the database at ``url`` into the private file ``into`` (SQLite's file, or pg_dump's archive);
    returns the revision and counts of the copy."""
    if kind == "postgresql":
        return _pg_dump(url, into)
    source = sqlite3.connect(f"{_sqlite_path(url).resolve().as_uri()}?mode=ro", uri=True, timeout=30)
    target = sqlite3.connect(into)
    try:
        source.backup(target)  # one read transaction: a snapshot of committed data
        target.execute("PRAGMA journal_mode=DELETE")  # one self-contained file, whatever the server used
    finally:
        target.close()
        source.close()
    return _summary(f"sqlite:///{into}")


def backup(url: str, out: str | Path) -> dict:
    """Back up the database at ``url`` into the new file ``out``; returns its manifest (kind, revision,
    participants, events, app version, the database's bytes and SHA-256) and the file's ``bytes``."""
    out = Path(out)
    kind = _kind(url)
    if kind == "sqlite" and not _sqlite_path(url).is_file():
        raise BackupError("no such database file", field="--db")
    tmp = _claim(out)
    payload = tmp.with_name(tmp.name + "." + PAYLOAD[kind].rsplit(".", 1)[1])
    try:
        _private_file(payload)
        summary = _dump(url, kind, payload)
        manifest = write_archive(payload, {"kind": kind, **summary, "app_version": scenesuggest.__version__,
                                           "created": _now()}, tmp)
        os.link(tmp, out)  # fails rather than replace a file made meanwhile
    except FileExistsError:
        raise BackupError("exists: a backup never replaces a file (choose another name)", file=str(out)) from None
    finally:
        tmp.unlink(missing_ok=True)
        payload.unlink(missing_ok=True)
    return {**manifest, "file_bytes": out.stat().st_size}


def _now() -> str:
    from datetime import UTC, datetime

    return datetime.now(UTC).isoformat(timespec="seconds")


def restore(source: str | Path, url: str) -> dict:
    """Restore the backup ``source`` into the empty database at ``url``; returns what it holds and the result
    of the database's integrity check. Refuses, before anything is kept, a file ``study backup`` did not write
    whole, and a database holding anything our migrations do not create."""
    source = Path(source)
    manifest = read_manifest(source)
    kind = _kind(url)
    if manifest["kind"] != kind:
        raise BackupError(f"a {manifest['kind']} backup restores into {manifest['kind']}, not into this {kind} "
                          "database", field="--db")
    if manifest["revision"] not in known_revisions():
        raise BackupError(f"made at schema revision {manifest['revision']!r}, which this version of the app does "
                          f"not know (it was made by {manifest['app_version']}): restore with that version",
                          file=str(source))
    done = _restore_sqlite(source, url) if kind == "sqlite" else _restore_pg(source, url)
    for key in ("revision", "participants", "events"):
        if done[key] != manifest[key]:
            raise BackupError(f"the restored database holds {key} {done[key]!r}, its manifest says "
                              f"{manifest[key]!r}: the backup is not what it claims", file=str(source))
    return {"kind": kind, **done, "sha256": manifest["sha256"], "app_version": manifest["app_version"]}


def _restore_sqlite(source: Path, url: str) -> dict:
    path = _sqlite_path(url)
    if path.exists() and path.stat().st_size and _tables(url):
        raise BackupError("the database is not empty: restore into a new one (a restore never mixes data)",
                          field="--db")
    path.parent.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(dir=path.parent, prefix=".restore-") as scratch:
        copy, built = Path(scratch) / "backup.sqlite3", Path(scratch) / "restored.sqlite3"
        _private_file(copy)
        manifest = extract_payload(source, copy, check_head=check_sqlite_head)
        try:
            check = sqlite3.connect(f"{copy.as_uri()}?mode=ro", uri=True).execute("PRAGMA integrity_check")
            verdict = check.fetchone()[0]
            check.connection.close()
        except sqlite3.DatabaseError as e:
            raise BackupError(f"the backup's database cannot be read ({e})", file=str(source)) from None
        if verdict != "ok":
            raise BackupError(f"the backup's database fails SQLite's integrity check ({verdict})", file=str(source))
        _private_file(built)
        migrate_to(f"sqlite:///{built}", manifest["revision"])  # the schema is ours; the backup gives only rows
        differences = sqlite_differences(sqlite_objects(copy), sqlite_objects(built))
        if differences:
            raise BackupError("holds what the migrations do not create, so nothing was restored: "
                              + "; ".join(differences), file=str(source))
        held = _summary(f"sqlite:///{copy}")
        for key in ("revision", "participants", "events"):
            if held[key] != manifest[key]:
                raise BackupError(f"the backup's database holds {key} {held[key]!r}, its manifest says "
                                  f"{manifest[key]!r}: the backup is not what it claims; nothing was restored",
                                  file=str(source))
        target = sqlite3.connect(built.as_uri(), uri=True)
        rows_only = (*SIGN_INS, "alembic_version")  # sign-ins stay behind; the migrations set the revision
        try:
            target.execute("ATTACH DATABASE ? AS backup", (f"{copy.as_uri()}?mode=ro",))
            problems = sqlite_value_problems(target, "backup", rows_only)
            if problems:
                raise BackupError("holds values the app cannot have written, so nothing was restored: "
                                  + "; ".join(problems[:10]) + (f"; and {len(problems) - 10} more"
                                                                 if len(problems) > 10 else ""), file=str(source))
            copy_sqlite_rows(target, "backup", rows_only)
            target.execute("DETACH DATABASE backup")
            check = target.execute("PRAGMA integrity_check").fetchone()[0]
        except sqlite3.DatabaseError as e:
            raise BackupError(f"the backup's rows cannot be stored ({e}); nothing was restored",
                              file=str(source)) from None
        finally:
            target.close()
        if check != "ok":
            raise BackupError(f"the restored database fails SQLite's integrity check ({check}); nothing was kept",
                              file=str(source))
        built.chmod(0o600)
        os.replace(built, path)
    return {**_summary(url), "integrity": check}


def _superuser(url: str) -> bool:
    with _connected(url) as con:
        return bool(con.execute(text("SELECT rolsuper FROM pg_roles WHERE rolname = current_user")).scalar())


def _reflected(con) -> MetaData:
    metadata = MetaData()
    metadata.reflect(con)
    return metadata


def _drop_everything(url: str) -> None:
    """Undo a refused restore: drop every table of ours (the database had none before it)."""
    with _connected(url, begin=True) as con:
        _reflected(con).drop_all(con)


def _restore_pg(source: Path, url: str) -> dict:
    if _superuser(url):
        raise BackupError("refusing to restore as a superuser: a dump is code, and a superuser runs whatever it "
                          "holds as the server's operating-system user; restore as the app's role (the owner of "
                          "the new database, e.g. DATABASE_URL=postgresql+psycopg://scenesuggest@…/restored)",
                          field="--db")
    if _tables(url):
        raise BackupError("the database is not empty: restore into a new one (a restore never mixes data)",
                          field="--db")
    tool = _pg_tool("pg_restore")
    uri, env = _libpq(url)
    with tempfile.TemporaryDirectory(prefix="scenesuggest-restore-") as scratch:
        archive = Path(scratch) / "backup.pgdump"
        _private_file(archive)
        manifest = extract_payload(source, archive)
        entries = pg_toc(tool, archive)
        refused = pg_refusals(entries, None)  # what no migration makes, before anything is written
        if refused:
            raise BackupError("holds what the migrations do not create, so nothing was restored: "
                              + "; ".join(refused), file=str(source))
        try:
            migrate_to(url, manifest["revision"])  # the schema is ours; the archive gives only rows
            reference = Path(scratch) / "reference.pgdump"
            _run([_pg_tool("pg_dump"), "--format=custom", "--schema-only", "--no-owner", "--no-password",
                  f"--file={reference}", f"--dbname={uri}"], env, "pg_dump")
            refused = pg_refusals(entries, pg_schema(pg_toc(tool, reference)))
            if refused:
                raise BackupError("holds what the migrations do not create, so nothing was restored: "
                                  + "; ".join(refused), file=str(source))
            order = {t: i for i, t in enumerate(_table_order(url))}
            rows = sorted(((order[name], line) for line, kind, _s, name in entries
                           if kind == "TABLE DATA" and name in order and name not in (*SIGN_INS, "alembic_version")),
                          key=lambda r: r[0])
            chosen = Path(scratch) / "rows.list"
            chosen.write_text("".join(line + "\n" for _o, line in rows))
            done = _copy_rows(tool, archive, chosen, url, env)
            for key in ("participants", "events"):
                if done[key] != manifest[key]:
                    raise BackupError(f"the archive holds {done[key]} {key}, its manifest says {manifest[key]}: "
                                      "the backup is not what it claims; nothing was kept", file=str(source))
        except BaseException:
            _drop_everything(url)
            raise
    return {**_summary(url), "integrity": "ok"}  # PostgreSQL checked every row in one transaction


_COPY = re.compile(r'^COPY public\.("?)([a-z_]+)\1 \((.*)\) FROM stdin;$')


def _copy_rows(tool: str, archive: Path, chosen: Path, url: str, env: dict) -> dict:
    """Load the archive's rows of the tables listed in ``chosen`` into the migrated database at ``url``, in one
    transaction, and set each table's id sequence after its largest id. Nothing of the archive runs: pg_restore
    only renders it as text (no connection), and of that text only COPY blocks of our tables, with columns they
    have, are read; the COPY statements sent are ours. Returns the participants and events counted before the
    transaction commits."""
    import psycopg.sql  # noqa: F401 - the helpers below need it: without it, nothing is started

    engine = create_engine(url)
    render = subprocess.Popen([tool, "--data-only", "--no-owner", "--no-privileges", f"--use-list={chosen}",
                               "--file=-", str(archive)], stdout=subprocess.PIPE, stderr=subprocess.PIPE, env=env)
    try:
        with engine.connect() as con:
            columns, counted = _columns_and_counted(con)
            raw = con.connection.dbapi_connection
            with raw.cursor() as cur:
                _load_copy_blocks(cur, iter(render.stdout), columns)
                _set_sequences(cur, counted)
                cur.execute("SELECT (SELECT COUNT(*) FROM participants), (SELECT COUNT(*) FROM events)")
                participants, events = cur.fetchone()
            if render.wait() != 0:
                last = (render.stderr.read().decode(errors="replace").strip().splitlines() or ["no message"])[-1]
                raise BackupError(f"pg_restore cannot read the archive's rows: {last}")
            con.commit()
    except SQLAlchemyError as e:
        raise BackupError(f"the archive's rows cannot be stored ({type(e).__name__}: {str(e).splitlines()[0]}); "
                          "nothing was kept") from None
    except Exception as e:  # psycopg's own errors (a COPY row that does not fit)
        if isinstance(e, BackupError):
            raise
        raise BackupError(f"the archive's rows cannot be stored ({type(e).__name__}: "
                          f"{str(e).splitlines()[0] if str(e) else ''}); nothing was kept") from None
    finally:
        if render.poll() is None:
            render.kill()
        render.wait()
        engine.dispose()
    return {"participants": participants, "events": events}


def _columns_and_counted(con) -> tuple[dict[str, set[str]], dict[str, int]]:
    """Each table's column names in the database, and the tables whose integer ``id`` a sequence gives, with the
    largest id a restore takes there (ID_LIMIT for ``integer``; for ``bigint``, which event ids outgrow 32 bits
    into, as many arrivals left as ``integer`` keeps)."""
    found = {t: inspect(con).get_columns(t) for t in inspect(con).get_table_names()}
    columns = {t: {c["name"] for c in cols} for t, cols in found.items()}
    limits = {"INTEGER": ID_LIMIT, "BIGINT": 2**63 - 1 - (2**31 - 1 - ID_LIMIT)}
    counted = {t: limits[str(c["type"])] for t, cols in found.items() for c in cols  # ids a sequence gives
               if c["name"] == "id" and str(c["type"]) in limits}
    return columns, counted


def _load_copy_blocks(cur, lines, columns: dict[str, set[str]]) -> None:
    """Load each COPY block of pg_restore's text ``lines`` (bytes) by a COPY of ours; nothing else is run."""
    from psycopg import sql

    for line in lines:
        match = _COPY.match(line.decode("utf-8", "replace").rstrip("\n"))
        if not match:
            continue  # SET, comments, anything else: never run
        table = match.group(2)
        names = [c.strip().strip('"') for c in match.group(3).split(",")]
        if table not in columns or table in (*SIGN_INS, "alembic_version") or \
                not set(names) <= columns[table]:
            raise BackupError(f"the archive's rows of {table!r} do not fit the migrations' table")
        statement = sql.SQL("COPY {} ({}) FROM STDIN").format(
            sql.Identifier("public", table), sql.SQL(", ").join(map(sql.Identifier, names)))
        with cur.copy(statement) as copy:
            for row in lines:
                if row == b"\\.\n":
                    break
                copy.write(row)


def _set_sequences(cur, counted: dict[str, int]) -> None:
    """Set the id sequence of each table of ``counted`` (but alembic_version) after its largest id, once every id
    is one the app can have written (from 1 to the table's limit: a sequence carried across keeps room for a
    billion arrivals)."""
    from psycopg import sql

    for table, limit in counted.items():
        if table != "alembic_version":
            low, high = cur.execute(sql.SQL("SELECT MIN(id), MAX(id) FROM {}").format(
                sql.Identifier("public", table))).fetchone()
            if low is not None and (low < 1 or high > limit):
                raise BackupError(f"{table}.id: ids from {low} to {high}, where the app writes ids from 1 up "
                                  f"(at most {limit}); nothing was kept")
            cur.execute(sql.SQL("SELECT setval(pg_get_serial_sequence({}, 'id'), "
                                "COALESCE(MAX(id), 0) + 1, false) FROM {} "
                                "WHERE pg_get_serial_sequence({}, 'id') IS NOT NULL").format(
                sql.Literal(f"public.{table}"), sql.Identifier("public", table),
                sql.Literal(f"public.{table}")))


def _table_order(url: str) -> list[str]:
    """Our tables, each after the tables its foreign keys name (the order rows are restored in)."""
    with _connected(url) as con:
        return [t.name for t in _reflected(con).sorted_tables]
