"""The schema only changes through migrations: every revision upgrades to head, and head matches the models."""

import pytest
from alembic.autogenerate import compare_metadata
from alembic.migration import MigrationContext
from alembic.script import ScriptDirectory
from conftest import make_app
from flask_migrate import downgrade, upgrade
from sqlalchemy import inspect

from study_server import MIGRATIONS
from study_server.extensions import db


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


@pytest.mark.parametrize("backend", ["sqlite", "postgresql"])
def test_upgrade_from_empty_and_from_every_revision(tmp_path, request, backend, demo_resources):
    url = request.getfixturevalue("postgres_db") if backend == "postgresql" else \
        f"sqlite:///{tmp_path / 'm.sqlite3'}"
    app = make_app(tmp_path, url)  # upgrades an empty database to head
    assert_schema_matches_models(app)
    revs = revisions()
    assert revs
    with app.app_context():
        for rev in ["base", *revs[:-1]]:
            downgrade(directory=str(MIGRATIONS), revision=rev)
            upgrade(directory=str(MIGRATIONS))
    assert_schema_matches_models(app)
