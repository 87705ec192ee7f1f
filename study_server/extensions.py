"""Flask extensions, created bare and bound to an app in :func:`study_server.create_app`."""

from flask_migrate import Migrate
from flask_sqlalchemy import SQLAlchemy
from sqlalchemy.orm import DeclarativeBase


class Base(DeclarativeBase):
    pass


db = SQLAlchemy(model_class=Base)
migrate = Migrate()


def dialect_insert(name: str):
    """The ``insert`` construct of a database (SQLite or PostgreSQL: both spell ``ON CONFLICT DO NOTHING``, each
    through its own dialect)."""
    if name == "postgresql":
        from sqlalchemy.dialects.postgresql import insert
    else:
        from sqlalchemy.dialects.sqlite import insert
    return insert


def insert_ignore(model, index_elements: list[str] | None = None):
    """``INSERT … ON CONFLICT DO NOTHING`` for the session's database."""
    return dialect_insert(db.session.get_bind().dialect.name)(model).on_conflict_do_nothing(
        index_elements=index_elements)
