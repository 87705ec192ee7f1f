"""Flask extensions, created bare and bound to an app in :func:`study_server.create_app`; the JSON text of the
database's JSON columns and of the app's answers."""

import json

import orjson
from flask.json.provider import DefaultJSONProvider
from flask_migrate import Migrate
from flask_sqlalchemy import SQLAlchemy
from sqlalchemy.orm import DeclarativeBase


class Base(DeclarativeBase):
    pass


db = SQLAlchemy(model_class=Base)
migrate = Migrate()


def dialect_insert(model):
    """An ``INSERT`` for the session's database that can say ``ON CONFLICT`` (SQLite and PostgreSQL spell it alike
    but through their own dialect)."""
    if db.session.get_bind().dialect.name == "postgresql":
        from sqlalchemy.dialects.postgresql import insert
    else:
        from sqlalchemy.dialects.sqlite import insert
    return insert(model)


def insert_ignore(model, index_elements: list[str] | None = None):
    """``INSERT … ON CONFLICT DO NOTHING`` for the session's database."""
    return dialect_insert(model).on_conflict_do_nothing(index_elements=index_elements)


#: orjson's options for the database's JSON: dict keys that are not text become text (as with json), numpy values
#: become numbers.
_OPTIONS = orjson.OPT_NON_STR_KEYS | orjson.OPT_SERIALIZE_NUMPY


def json_text(value) -> str:
    """The JSON text a JSON column stores for ``value`` (the engine's serializer). orjson: the events' payloads are
    mostly floats (4×4 transforms), which json.dumps writes ten times slower; a value orjson cannot write (an
    integer past 64 bits) is written by json. Not-a-number writes as null (standard JSON; json would write NaN)."""
    try:
        return orjson.dumps(value, option=_OPTIONS).decode()
    except orjson.JSONEncodeError:
        return json.dumps(value)


def json_value(text: str | bytes):
    """The value of JSON ``text`` (the engine's deserializer; the API's request bodies): orjson, or json for what
    orjson refuses — NaN or Infinity (which json.dumps wrote), a number past a double's range, a lone surrogate —
    whose value, or error (a ValueError, or RecursionError when nested thousands deep), is then json's. An integer
    past 64 bits reads as the nearest double (the integers the server keeps — seqs, ranks, window sizes — are
    bounded far below that; a number field may hold one, and means the number)."""
    try:
        return orjson.loads(text)
    except orjson.JSONDecodeError:
        return json.loads(text)


class Answers(DefaultJSONProvider):
    """The app's JSON answers (``jsonify``) written by orjson: a suggestion list's answer (about 23 kB) took
    json.dumps, with Flask's sorted keys, a quarter of a millisecond, orjson a sixtieth. Keys stay in the order
    the answer was made in; text is UTF-8, not \\u-escaped; not-a-number writes as null (standard JSON, which a
    browser's ``JSON.parse`` reads; json would write NaN); dates as Flask writes them. What orjson cannot write
    (an integer past 64 bits) and indented answers (debug mode) are Flask's own, as is the JSON the templates
    write (``tojson``)."""

    def response(self, *args, **kwargs):
        if (self.compact is None and self._app.debug) or self.compact is False:
            return super().response(*args, **kwargs)
        obj = self._prepare_response_obj(args, kwargs)
        try:
            text = orjson.dumps(obj, default=self.default, option=_OPTIONS | orjson.OPT_PASSTHROUGH_DATETIME)
        except orjson.JSONEncodeError:
            return super().response(*args, **kwargs)
        return self._app.response_class(text + b"\n", mimetype=self.mimetype)
