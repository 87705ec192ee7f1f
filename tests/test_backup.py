"""Backups that restore (``study backup`` / ``study restore``), on SQLite and PostgreSQL: taken while simulated
participants are mid-study, restored into a fresh database, they hold exactly what was stored when taken."""

import csv
import subprocess
import sys
import threading
import time

import pytest
from demostudy import make_app
from sqlalchemy import create_engine, text

from simulation.run import simulate
from study_server.experimenter.backup import BackupError, backup, restore
from study_server.experimenter.export import export_to


def fresh_database(request, backend_url, tmp_path):
    """A second empty database beside ``backend_url``, on the same kind of server."""
    if backend_url.startswith("sqlite"):
        return f"sqlite:///{tmp_path / 'restored.sqlite3'}"
    return request.getfixturevalue("postgres_server").create("restored", owner="app")


def stored_events(url):
    engine = create_engine(url)
    try:
        with engine.connect() as con:
            return con.execute(text("SELECT COUNT(*) FROM events")).scalar()
    finally:
        engine.dispose()


def events_csv(app, out):
    with app.app_context():
        export_to(app.extensions["studies"]["demo"], out)
    with open(out / "events.csv", newline="") as f:
        return [tuple(row) for row in csv.reader(f)][1:]


@pytest.mark.slow
def test_a_backup_taken_mid_study_restores_what_was_stored_then(request, backend_url, tmp_path):
    app = make_app(tmp_path, backend_url)
    result = {}
    bots = threading.Thread(target=lambda: result.update(simulate(10, seed=3, study="demo", app=app)))
    bots.start()
    deadline = time.monotonic() + 120
    while stored_events(backend_url) < 1500 and time.monotonic() < deadline and bots.is_alive():
        time.sleep(0.05)
    taken = backup(backend_url, tmp_path / "mid-study.backup")
    bots.join()
    assert result["completed"] == 10 and not result["failures"]
    assert 0 < taken["events"] < result["events"]  # taken mid-study
    with pytest.raises(BackupError, match="never replaces a file"):
        backup(backend_url, tmp_path / "mid-study.backup")

    target = fresh_database(request, backend_url, tmp_path)
    restored = restore(tmp_path / "mid-study.backup", target)
    assert restored["integrity"] == "ok" and restored["events"] == taken["events"]
    assert restored["participants"] == taken["participants"] and restored["revision"] == taken["revision"]
    with pytest.raises(BackupError, match="not empty"):
        restore(tmp_path / "mid-study.backup", target)

    live = events_csv(app, tmp_path / "live")
    then = events_csv(make_app(tmp_path / "restored-app", target), tmp_path / "then")
    assert len(then) == taken["events"] and set(then) <= set(live)  # every stored event, as it is live
    by_participant = {}
    for row in then:
        by_participant.setdefault(row[0], []).append(int(row[1]))
    assert all(seqs == list(range(len(seqs))) for seqs in by_participant.values())  # a prefix of each log


def test_restore_refuses_what_it_cannot_restore_and_names_it(tmp_path, demo_resources):
    app = make_app(tmp_path)
    url = app.config["SQLALCHEMY_DATABASE_URI"]
    (tmp_path / "notes.txt").write_text("not a backup")
    with pytest.raises(BackupError, match="not a backup"):
        restore(tmp_path / "notes.txt", f"sqlite:///{tmp_path / 'a.sqlite3'}")
    taken = backup(url, tmp_path / "b.backup")
    assert taken["kind"] == "sqlite" and taken["participants"] == 0
    assert (tmp_path / "b.backup").stat().st_mode & 0o077 == 0  # private, as the database is
    with pytest.raises(BackupError) as info:
        restore(tmp_path / "b.backup", "postgresql+psycopg://u@127.0.0.1:1/x")
    assert "a sqlite backup restores into sqlite" in info.value.message and info.value.field == "--db"
    other = tmp_path / "other.sqlite3"
    import sqlite3

    with sqlite3.connect(other) as con:
        con.execute("CREATE TABLE mine (x)")
    with pytest.raises(BackupError, match="not empty"):
        restore(tmp_path / "b.backup", f"sqlite:///{other}")
    foreign = tmp_path / "foreign.sqlite3"
    with sqlite3.connect(foreign) as con:
        con.execute("CREATE TABLE mine (x)")
    with pytest.raises(BackupError, match="not a backup written by 'study backup'"):
        restore(foreign, f"sqlite:///{tmp_path / 'c.sqlite3'}")
    assert not (tmp_path / "c.sqlite3").exists()


def test_the_commands_back_up_and_restore(tmp_path, demo_resources):
    app = make_app(tmp_path)
    url = app.config["SQLALCHEMY_DATABASE_URI"]

    def cli(*args):
        return subprocess.run([sys.executable, "-m", "scenesuggest.cli", "study", *args], capture_output=True,
                              text=True)

    made = cli("backup", "--db", url, "--out", str(tmp_path / "x.backup"))
    assert made.returncode == 0 and "backed up 0 participants" in made.stdout, made.stderr
    back = cli("restore", str(tmp_path / "x.backup"), "--db", f"sqlite:///{tmp_path / 'y.sqlite3'}")
    assert back.returncode == 0 and "integrity ok" in back.stdout, back.stderr
    again = cli("restore", str(tmp_path / "x.backup"), "--db", f"sqlite:///{tmp_path / 'y.sqlite3'}")
    assert again.returncode == 2 and "not empty" in again.stderr
