"""A restore only accepts what ``study backup`` wrote and our migrations define: a backup carrying triggers, views,
functions or changed tables is refused by name, a changed byte fails its digest, a damaged or sparse file is
refused before anything is written, and neither sign-ins nor a file's loose permissions come across."""

import io
import json
import sqlite3
import subprocess
import sys
import tarfile

import pytest
from demostudy import make_app
from sqlalchemy import create_engine, inspect, text

from study_server.experimenter.backup import BackupError, backup, restore
from study_server.experimenter.backup_archive import MANIFEST, write_archive
from study_server.participants.assignment import arrive, assign


def run(url: str, *statements: str) -> None:
    engine = create_engine(url)
    try:
        with engine.begin() as con:
            for statement in statements:
                con.execute(text(statement))
    finally:
        engine.dispose()


def tables(url: str) -> list[str]:
    engine = create_engine(url)
    try:
        with engine.connect() as con:
            return inspect(con).get_table_names()
    finally:
        engine.dispose()


def cli(*args):
    return subprocess.run([sys.executable, "-m", "scenesuggest.cli", "study", *args], capture_output=True, text=True)


def one_participant(app) -> str:
    """One participant arrived and consented in ``app``'s demo study; returns its database URL."""
    with app.app_context():
        study = app.extensions["studies"]["demo"].study
        participant, _ = arrive(study, "link", "p1")
        assign(study, participant)
    return app.config["SQLALCHEMY_DATABASE_URI"]


@pytest.fixture
def study_db(tmp_path, demo_resources):
    """A migrated SQLite study database with one participant and their trials."""
    return one_participant(make_app(tmp_path / "source"))


def backdoored(url: str) -> None:
    """What an attacker with write access to a backup adds: a trigger giving every new participant a known
    token, one undoing an exclusion, a view."""
    run(url, "CREATE TRIGGER known_token AFTER INSERT ON participants BEGIN "
             "UPDATE participants SET token = 'known' WHERE id = NEW.id; END",
        "CREATE TRIGGER undo_exclusion AFTER UPDATE OF status ON participants WHEN NEW.status = 'excluded' BEGIN "
        "UPDATE participants SET status = 'in_progress' WHERE id = NEW.id; END",
        "CREATE VIEW everyone AS SELECT token FROM participants")


def test_a_sqlite_backup_with_triggers_or_a_view_is_refused_naming_each(study_db, tmp_path):
    backdoored(study_db)
    backup(study_db, tmp_path / "b.backup")  # its digest is right: it is the database that is hostile
    target = tmp_path / "restored.sqlite3"
    with pytest.raises(BackupError) as info:
        restore(tmp_path / "b.backup", f"sqlite:///{target}")
    message = info.value.message
    assert "trigger 'known_token' on participants" in message and "trigger 'undo_exclusion'" in message
    assert "view 'everyone'" in message and "nothing was restored" in message
    assert not target.exists()
    assert not list(tmp_path.glob(".restore-*"))  # the scratch copies are gone


def test_a_trigger_named_like_sqlites_own_tables_is_refused(study_db, tmp_path):
    import sqlite3 as lite

    path = study_db.removeprefix("sqlite:///")
    with lite.connect(path) as con:
        con.execute("PRAGMA writable_schema = ON")
        con.execute("INSERT INTO sqlite_master (type, name, tbl_name, rootpage, sql) VALUES ('trigger', "
                    "'sqlite_stat9', 'participants', 0, 'CREATE TRIGGER sqlite_stat9 AFTER INSERT ON participants "
                    "BEGIN UPDATE participants SET token = ''known'' WHERE id = NEW.id; END')")
    backup(study_db, tmp_path / "b.backup")
    with pytest.raises(BackupError, match="trigger 'sqlite_stat9' on participants"):
        restore(tmp_path / "b.backup", f"sqlite:///{tmp_path / 'r.sqlite3'}")
    assert not (tmp_path / "r.sqlite3").exists()


def test_a_changed_table_or_an_extra_index_is_refused(study_db, tmp_path):
    run(study_db, "ALTER TABLE surveys ADD COLUMN note TEXT", "CREATE INDEX ix_extra ON events (type)")
    backup(study_db, tmp_path / "b.backup")
    with pytest.raises(BackupError) as info:
        restore(tmp_path / "b.backup", f"sqlite:///{tmp_path / 'r.sqlite3'}")
    assert "table 'surveys' is not as the migrations create it" in info.value.message
    assert "index 'ix_extra' on events (not made by the migrations)" in info.value.message


def test_four_changed_bytes_fail_the_digest_and_nothing_is_written(study_db, tmp_path):
    made = backup(study_db, tmp_path / "b.backup")
    data = bytearray((tmp_path / "b.backup").read_bytes())
    at = data.index(b"SQLite format 3\x00") + made["bytes"] // 2
    data[at:at + 4] = bytes(b ^ 0xFF for b in data[at:at + 4])
    (tmp_path / "b.backup").write_bytes(bytes(data))
    target = tmp_path / "restored.sqlite3"
    with pytest.raises(BackupError, match="does not match its SHA-256"):
        restore(tmp_path / "b.backup", f"sqlite:///{target}")
    assert not target.exists()


def test_a_forged_page_count_is_refused_before_the_rest_is_written(study_db, tmp_path):
    made = backup(study_db, tmp_path / "b.backup")
    with tarfile.open(tmp_path / "b.backup") as tar:
        payload = bytearray(tar.extractfile("database.sqlite3").read())
    payload[28:32] = (10 ** 6).to_bytes(4, "big")  # a million pages, in a file of a few dozen
    (tmp_path / "forged.sqlite3").write_bytes(bytes(payload))
    out = tmp_path / "forged.backup"
    out.touch(0o600)
    write_archive(tmp_path / "forged.sqlite3", {k: made[k] for k in ("kind", "revision", "participants", "events",
                                                                   "app_version")}, out)
    with pytest.raises(BackupError, match="header says 1000000 pages"):
        restore(out, f"sqlite:///{tmp_path / 'r.sqlite3'}")


def test_a_sparse_file_claiming_gigabytes_is_refused_before_anything_is_written(tmp_path):
    from study_server.experimenter.backup_schema import known_revisions

    manifest = json.dumps({"format": "scenesuggest-backup/1", "kind": "sqlite", "payload": "database.sqlite3",
                           "revision": sorted(known_revisions())[0], "participants": 0, "events": 0, "app_version": "0",
                           "bytes": 4 << 30, "sha256": "0" * 64}).encode()
    out = tmp_path / "sparse.backup"
    with tarfile.open(out, "w") as tar:
        info = tarfile.TarInfo(MANIFEST)
        info.size = len(manifest)
        tar.addfile(info, io.BytesIO(manifest))
    with out.open("r+b") as f:
        f.truncate(4 << 30)  # holes: gigabytes long, nothing written
    target = tmp_path / "r.sqlite3"
    with pytest.raises(BackupError, match="holds no database.sqlite3"):
        restore(out, f"sqlite:///{target}")
    assert not target.exists()


@pytest.mark.parametrize("damage", ["truncated", "garbage", "empty"])
def test_a_damaged_file_is_an_error_with_exit_2_not_a_traceback(study_db, tmp_path, damage):
    backup(study_db, tmp_path / "b.backup")
    whole = (tmp_path / "b.backup").read_bytes()
    broken = {"truncated": whole[:len(whole) * 2 // 3], "garbage": bytes(range(256)) * 40, "empty": b""}[damage]
    (tmp_path / "x.backup").write_bytes(broken)
    done = cli("restore", str(tmp_path / "x.backup"), "--db", f"sqlite:///{tmp_path / 'r.sqlite3'}")
    assert done.returncode == 2 and done.stderr.startswith("Error: ") and "Traceback" not in done.stderr, done.stderr
    assert "x.backup" in done.stderr and not (tmp_path / "r.sqlite3").exists()


def test_an_unknown_revision_is_refused_naming_the_version_that_made_it(study_db, tmp_path):
    made = backup(study_db, tmp_path / "b.backup")
    with tarfile.open(tmp_path / "b.backup") as tar:
        (tmp_path / "db.sqlite3").write_bytes(tar.extractfile("database.sqlite3").read())
    out = tmp_path / "future.backup"
    out.touch(0o600)
    write_archive(tmp_path / "db.sqlite3", {"kind": "sqlite", "revision": "ffffffffffff", "participants": 1,
                                            "events": made["events"], "app_version": "9.9.9"}, out)
    with pytest.raises(BackupError, match="revision 'ffffffffffff'.*made by 9.9.9"):
        restore(out, f"sqlite:///{tmp_path / 'r.sqlite3'}")


def test_sign_ins_stay_behind_and_an_existing_file_becomes_private(study_db, tmp_path):
    run(study_db, "INSERT INTO login_attempts (ip, ok, at) VALUES ('203.0.113.9', 0, '2026-01-01 00:00:00')",
        "INSERT INTO admin_sessions (id, created_at, last_seen_at) VALUES ('s', '2026-01-01', '2026-01-01')")
    made = backup(study_db, tmp_path / "b.backup")
    assert made["participants"] == 1
    target = tmp_path / "restored.sqlite3"
    target.touch(0o644)
    target.chmod(0o644)
    done = restore(tmp_path / "b.backup", f"sqlite:///{target}")
    assert done["participants"] == 1 and done["integrity"] == "ok" and done["sha256"] == made["sha256"]
    assert target.stat().st_mode & 0o777 == 0o600
    with sqlite3.connect(target) as con:
        assert con.execute("SELECT COUNT(*) FROM login_attempts").fetchone()[0] == 0
        assert con.execute("SELECT COUNT(*) FROM admin_sessions").fetchone()[0] == 0
        assert con.execute("SELECT COUNT(*) FROM participants").fetchone()[0] == 1


def test_a_trigger_named_like_an_index_of_the_migrations_is_refused(study_db, tmp_path):
    """SQLite keeps triggers in a namespace of their own: a trigger may share the name of one of our indexes, made
    again after it, so that keying the schema by name alone would see only the index."""
    run(study_db, "DROP INDEX ix_participants_token",
        "CREATE TRIGGER ix_participants_token AFTER INSERT ON participants BEGIN "
        "UPDATE participants SET token = 'backdoor-4' WHERE id = NEW.id; END",
        "CREATE UNIQUE INDEX ix_participants_token ON participants (token)")
    backup(study_db, tmp_path / "b.backup")
    with pytest.raises(BackupError, match="trigger 'ix_participants_token' on participants, named like an object "
                                          "of the migrations"):
        restore(tmp_path / "b.backup", f"sqlite:///{tmp_path / 'r.sqlite3'}")
    assert not (tmp_path / "r.sqlite3").exists()


def test_nothing_of_a_backups_schema_reaches_the_restored_database_even_unchecked(study_db, tmp_path, monkeypatch):
    """The migrations build the restored schema and only rows are copied in: were the schema check ever to miss
    one, no trigger or view of a backup would come across, and a new participant's token is the app's own."""
    import study_server.experimenter.backup as backup_module

    backdoored(study_db)
    run(study_db, "CREATE TRIGGER ix_participants_row AFTER INSERT ON participants BEGIN "
                  "UPDATE participants SET token = 'backdoor-4' WHERE id = NEW.id; END")
    backup(study_db, tmp_path / "b.backup")
    monkeypatch.setattr(backup_module, "sqlite_differences", lambda *_: [])
    target = tmp_path / "r.sqlite3"
    done = restore(tmp_path / "b.backup", f"sqlite:///{target}")
    assert done["participants"] == 1 and done["integrity"] == "ok"
    with sqlite3.connect(target) as con:
        assert con.execute("SELECT type, name FROM sqlite_master WHERE type IN ('trigger', 'view')").fetchall() == []
    app = make_app(tmp_path / "served", f"sqlite:///{target}")
    with app.app_context():
        participant, _ = arrive(app.extensions["studies"]["demo"].study, "link", "p2")
        from study_server.base.extensions import db
        from study_server.base.models import Participant

        assert db.session.get(Participant, participant.id).token not in ("known", "backdoor-4")


@pytest.mark.parametrize(("statement", "named"), [
    ("UPDATE participants SET created_at = 'yesterday'", "participants.created_at: 1 value"),
    ("UPDATE participants SET created_at = '2026-02-31 10:00:00.000000'", "participants.created_at"),
    ("UPDATE participants SET created_at = '2026-13-45 10:00:00'", "participants.created_at"),
    ("UPDATE participants SET last_seen_at = '2026-01-01 25:00:00'", "participants.last_seen_at"),
    ("UPDATE participants SET created_at = '0000-01-01 00:00:00'", "participants.created_at"),
    ("UPDATE participants SET token = 'abc' || char(0) || hex(randomblob(400))", "participants.token"),
    ("UPDATE participants SET flags = '[]' || char(0) || 'garbage'", "participants.flags"),
    ("UPDATE participants SET flags = '[not json'", "participants.flags: 1 value"),
    ("UPDATE participants SET row = 'one'", "participants.row"),
    ("UPDATE participants SET token = X'00ff'", "participants.token"),
    ("UPDATE participants SET platform = 'a platform longer than sixteen'", "participants.platform"),
    ("UPDATE participants SET pilot = 2", "participants.pilot"),
    ("UPDATE trials SET id = 2147483646 WHERE id = (SELECT MAX(id) FROM trials)", "trials.id: 1 value"),
    ("UPDATE trials SET participant_id = 99 WHERE id = (SELECT MIN(id) FROM trials)",
     "trials: 1 row naming a participants row that does not exist"),
])
def test_values_the_app_cannot_have_written_are_refused_by_table_column_and_row(study_db, tmp_path, statement,
                                                                                named):
    """One forged cell (a time that is no time, flags that are not JSON, an id at the end of PostgreSQL's range,
    a row naming no participant) would take down every admin page or the export: it is named, and nothing is
    restored."""
    run(study_db, statement)
    backup(study_db, tmp_path / "b.backup")
    with pytest.raises(BackupError) as info:
        restore(tmp_path / "b.backup", f"sqlite:///{tmp_path / 'r.sqlite3'}")
    assert "values the app cannot have written" in info.value.message and named in info.value.message
    assert "nothing was restored" in info.value.message
    assert not (tmp_path / "r.sqlite3").exists()


def test_sqlites_statistics_are_never_carried_across(study_db, tmp_path):
    """A forged sqlite_stat1 (a table SQLite itself keeps) would turn the look-up before every suggestion into a
    scan: the restored database plans its queries as the app's own does, from no statistics."""
    run(study_db, "ANALYZE")
    run(study_db, "DELETE FROM sqlite_stat1",
        "INSERT INTO sqlite_stat1 VALUES ('lists', 'ix_lists_participant_created', '1 1000000 1000000')")
    backup(study_db, tmp_path / "b.backup")
    target = tmp_path / "r.sqlite3"
    restore(tmp_path / "b.backup", f"sqlite:///{target}")
    with sqlite3.connect(target) as con:
        assert con.execute("SELECT name FROM sqlite_master WHERE name LIKE 'sqlite_stat%'").fetchall() == []
        plan = " ".join(str(r) for r in con.execute(
            "EXPLAIN QUERY PLAN SELECT COUNT(*) FROM lists WHERE participant_id = 1 AND created_at >= '2026'"))
        assert "ix_lists_participant_created" in plan, plan


def test_a_sparse_backup_is_refused_before_its_payload_is_expanded(tmp_path, study_db):
    """A backup whose database is mostly holes (a real SQLite header, then hundreds of megabytes that take no disk;
    size and SHA-256 recomputed as anyone who can write the file can) is refused from its size on disk, before a
    byte of the payload is written or even hashed."""
    import hashlib

    made = backup(study_db, tmp_path / "b.backup")
    with tarfile.open(tmp_path / "b.backup") as tar:
        head = bytearray(tar.extractfile("database.sqlite3").read(4096))
    claimed = 256 << 20
    head[28:32] = (claimed // 4096).to_bytes(4, "big")
    digest = hashlib.sha256(bytes(head))
    zeros = bytes(1 << 20)
    for _ in range((claimed - 4096) >> 20):
        digest.update(zeros)
    digest.update(bytes((claimed - 4096) % (1 << 20)))
    manifest = json.dumps({"format": "scenesuggest-backup/1", "kind": "sqlite", "payload": "database.sqlite3",
                           **{k: made[k] for k in ("revision", "participants", "events", "app_version")},
                           "bytes": claimed, "sha256": digest.hexdigest()}).encode()
    out = tmp_path / "sparse.backup"
    with out.open("wb") as f:
        for name, size, body in ((MANIFEST, len(manifest), manifest), ("database.sqlite3", claimed, bytes(head))):
            info = tarfile.TarInfo(name)
            info.size = size
            f.write(info.tobuf(tarfile.PAX_FORMAT))
            f.write(body + bytes(-len(body) % 512))
            if name != MANIFEST:
                f.seek(size - len(body) + (-size % 512), 1)
        f.write(bytes(1024))
    assert out.stat().st_blocks * 512 < claimed // 100  # holes
    scratch_sizes = []
    import study_server.experimenter.backup_archive as archive

    real_extract = archive.extract_payload

    def watched(source, into, check_head=None):
        try:
            return real_extract(source, into, check_head)
        finally:
            scratch_sizes.append(into.stat().st_size)

    import study_server.experimenter.backup as backup_module

    backup_module.extract_payload = watched
    try:
        with pytest.raises(BackupError, match="the file has holes where they should be"):
            restore(out, f"sqlite:///{tmp_path / 'r.sqlite3'}")
    finally:
        backup_module.extract_payload = real_extract
    assert scratch_sizes == [0] and not (tmp_path / "r.sqlite3").exists()


# --- PostgreSQL ---------------------------------------------------------------------------------------------------
@pytest.fixture
def pg_source(postgres_server, tmp_path, demo_resources):
    url = postgres_server.create("source_" + tmp_path.name[-12:].lower().replace("-", "_"))
    return one_participant(make_app(tmp_path / "pg-source", url))


def test_postgres_is_restored_as_the_apps_role_and_never_by_a_superuser(pg_source, postgres_server, tmp_path):
    run(pg_source, "INSERT INTO login_attempts (ip, ok, at) VALUES ('203.0.113.9', false, now())")
    backup(pg_source, tmp_path / "b.backup")
    name = "as_super_" + tmp_path.name[-8:].lower().replace("-", "_")
    superuser = postgres_server.create(name)
    with pytest.raises(BackupError, match="refusing to restore as a superuser"):
        restore(tmp_path / "b.backup", superuser)
    assert tables(superuser) == []
    app_role = postgres_server.create("as_app_" + tmp_path.name[-8:].lower().replace("-", "_"), owner="app")
    done = restore(tmp_path / "b.backup", app_role)
    assert done["participants"] == 1 and done["integrity"] == "ok"
    engine = create_engine(app_role)
    try:
        with engine.connect() as con:
            assert con.execute(text("SELECT COUNT(*) FROM login_attempts")).scalar() == 0
            assert con.execute(text("SELECT COUNT(*) FROM participants")).scalar() == 1
    finally:
        engine.dispose()


def test_a_postgres_archive_with_a_function_a_trigger_or_a_view_is_refused_before_anything_runs(
        pg_source, postgres_server, tmp_path):
    run(pg_source,
        "CREATE FUNCTION evil() RETURNS trigger LANGUAGE plpgsql AS $$ BEGIN NEW.token := 'known'; "
        "RETURN NEW; END $$",
        "CREATE TRIGGER known_token BEFORE INSERT ON participants FOR EACH ROW EXECUTE FUNCTION evil()",
        "CREATE VIEW everyone AS SELECT token FROM participants",
        "CREATE RULE no_exclusions AS ON UPDATE TO participants WHERE NEW.status = 'excluded' DO INSTEAD NOTHING")
    backup(pg_source, tmp_path / "b.backup")
    target = postgres_server.create("evil_" + tmp_path.name[-8:].lower().replace("-", "_"), owner="app")
    with pytest.raises(BackupError) as info:
        restore(tmp_path / "b.backup", target)
    message = info.value.message
    for named in ("FUNCTION public evil()", "TRIGGER public participants known_token", "VIEW public everyone",
                  "RULE public participants no_exclusions"):
        assert named in message, message
    assert tables(target) == []


def refused_as_the_apps_role(pg_source, postgres_server, tmp_path, statement: str, words: str) -> None:
    """The source changed by ``statement``, backed up and restored as the app's role into a new database: refused
    with ``words``, and the database left without a table."""
    run(pg_source, statement)
    backup(pg_source, tmp_path / "b.backup")
    target = postgres_server.create("t_" + tmp_path.name[-8:].lower().replace("-", "_"), owner="app")
    with pytest.raises(BackupError, match=words):
        restore(tmp_path / "b.backup", target)
    assert tables(target) == []


def test_a_postgres_archive_with_an_extra_index_is_refused_and_nothing_is_kept(pg_source, postgres_server,
                                                                              tmp_path):
    refused_as_the_apps_role(pg_source, postgres_server, tmp_path, "CREATE INDEX ix_extra ON events (type)",
                             "INDEX ix_extra")


def test_a_postgres_id_near_the_end_of_its_sequence_is_refused_and_nothing_is_kept(pg_source, postgres_server,
                                                                                   tmp_path):
    """An id of 2³¹ − 2 would leave the restored sequence one arrival from its end."""
    refused_as_the_apps_role(pg_source, postgres_server, tmp_path,
                             "UPDATE trials SET id = 2147483646 WHERE id = (SELECT MAX(id) FROM trials)",
                             "trials.id: ids from 1 to 2147483646")
