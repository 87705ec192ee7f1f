"""Flask extensions, created bare and bound to an app in :func:`study_server.create_app`."""

from flask_migrate import Migrate
from flask_sqlalchemy import SQLAlchemy
from sqlalchemy.orm import DeclarativeBase


class Base(DeclarativeBase):
    pass


db = SQLAlchemy(model_class=Base)
migrate = Migrate()


def insert_ignore(model, index_elements: list[str] | None = None):
    """``INSERT … ON CONFLICT DO NOTHING`` for the session's database (SQLite or PostgreSQL spell it alike but
    through their own dialect)."""
    if db.session.get_bind().dialect.name == "postgresql":
        from sqlalchemy.dialects.postgresql import insert
    else:
        from sqlalchemy.dialects.sqlite import insert
    return insert(model).on_conflict_do_nothing(index_elements=index_elements)
