"""The schema only changes through migrations: every revision upgrades to head, and head matches the models."""

from alembic.autogenerate import compare_metadata
from alembic.migration import MigrationContext
from alembic.script import ScriptDirectory
from demostudy import make_app
from flask_migrate import downgrade, upgrade
from sqlalchemy import inspect

from study_server import MIGRATIONS
from study_server.base.extensions import db


def revisions():
    script = ScriptDirectory.from_config(_config())
    return [r.revision for r in reversed(list(script.walk_revisions()))]


def _config():
    from alembic.config import Config

    cfg = Config(str(MIGRATIONS / "alembic.ini"))
    cfg.set_main_option("script_location", str(MIGRATIONS))
    return cfg


def assert_schema_matches_models(app):
    with app.app_context(), db.engine.connect() as conn:
        diffs = compare_metadata(MigrationContext.configure(conn), db.metadata)
        assert diffs == []
        assert set(inspect(conn).get_table_names()) >= {"participants", "events", "trials", "lists", "surveys",
                                                         "session_log", "studies", "login_attempts"}


def test_upgrade_from_empty_and_from_every_revision(tmp_path, backend_url, demo_resources):
    url = backend_url
    app = make_app(tmp_path, url)  # upgrades an empty database to head
    assert_schema_matches_models(app)
    revs = revisions()
    assert revs
    with app.app_context():
        for rev in ["base", *revs[:-1]]:
            downgrade(directory=str(MIGRATIONS), revision=rev)
            upgrade(directory=str(MIGRATIONS))
    assert_schema_matches_models(app)


def test_a_waiting_replay_check_written_as_prose_moves_into_its_column(tmp_path, backend_url):
    """Trials stored before the check's wait had a column of its own said it in ``replay``; the migration reads
    it from there, on both databases."""
    from flowhelp import auth, to_trials

    from study_server.base.models import Trial

    app = make_app(tmp_path, backend_url)
    c = app.test_client()
    b = to_trials(c)
    assert c.post("/api/trial/done", headers=auth(b), json={"trial": -1, "last_seq": 7}).status_code == 200
    with app.app_context():
        db.session.query(Trial).filter_by(index=-1).one().replay_waits_for = None
        db.session.commit()
        downgrade(directory=str(MIGRATIONS), revision="5c1e7d9a3f20")
        upgrade(directory=str(MIGRATIONS))
        waiting = db.session.query(Trial).filter_by(index=-1).one()
        assert (waiting.replay, waiting.replay_waits_for) == ("pending: events up to seq 7 not stored yet", 7)
        assert db.session.query(Trial).filter(Trial.replay_waits_for.is_not(None)).count() == 1
