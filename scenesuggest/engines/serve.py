"""Any registered engine as an HTTP engine: answers the study server's queries (:data:`.wire.QUERY_SCHEMA`) with
answers (:data:`.wire.ANSWER_SCHEMA`) — the reference implementation of the protocol, and a way to run an engine
in a process (or on a machine) of its own.

``scenesuggest engine serve NAME --priors FILE --port N``. One POST per query, to any path; a query that cannot be
read gets 400 with ``{"error": …}``. Threads serve connections (kept alive); loopback by default.
"""

from __future__ import annotations

import time
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer

import orjson

from ..errors import SceneSuggestError
from ..scenes.scene_json import from_dict
from ..suggestion.query import ContextQuery
from ..suggestion.suggest import MODES
from .protocol import SuggestionEngine
from .wire import answer_item

#: The largest query read (bytes): a scene of a few hundred objects is well below it.
MAX_QUERY_BYTES = 8 << 20
#: Models named per suggestion (a study shows a dozen; the protocol allows MAX_MODELS).
ANSWER_MODELS = 12


def answer(engine: SuggestionEngine, doc) -> dict:
    """The answer document to a query document; :class:`SceneSuggestError` naming the field for a bad query."""
    if not isinstance(doc, dict):
        raise SceneSuggestError("expected a JSON object", field="query")
    mode, top, categories = doc.get("mode"), doc.get("top"), doc.get("categories")
    if mode not in MODES:
        raise SceneSuggestError(f"expected one of {', '.join(MODES)}", field="mode")
    if isinstance(top, bool) or not isinstance(top, int) or top < 1:
        raise SceneSuggestError("expected a positive integer", field="top")
    if not isinstance(categories, list) or not all(isinstance(c, str) for c in categories):
        raise SceneSuggestError("expected a list of category names", field="categories")
    if not isinstance(doc.get("scene"), dict):
        raise SceneSuggestError("expected a scene in the native format", field="scene")
    scene = from_dict({"format": "scenesuggest-scene", "version": 1, "id": "query", **doc["scene"]})
    query = ContextQuery(scene, doc.get("parent"), doc.get("point"), doc.get("normal"), doc.get("scene_type"))
    found = engine.suggest(query, mode, top, only=categories)
    return {"suggestions": [answer_item(s, ANSWER_MODELS) for s in found]}


def make_server(engine: SuggestionEngine, host: str = "127.0.0.1", port: int = 0) -> ThreadingHTTPServer:
    """An HTTP server (not yet serving) that answers queries with ``engine``; ``port`` 0 picks a free one."""

    class Handler(BaseHTTPRequestHandler):
        protocol_version = "HTTP/1.1"
        disable_nagle_algorithm = True  # headers and body leave at once, not after a delayed ACK

        def do_POST(self):  # noqa: N802 - the name http.server calls
            length = self.headers.get("Content-Length", "")
            number = length.isascii() and length.isdigit()
            if not number or int(length) > MAX_QUERY_BYTES:
                self.close_connection = True  # the body is not read: the connection cannot carry another query
                return self._send(413 if number else 411, {"error": "a query needs a Content-Length of at most "
                                                                    f"{MAX_QUERY_BYTES} bytes"})
            data = self.rfile.read(int(length))
            started = time.perf_counter()
            try:
                self._send(200, answer(engine, orjson.loads(data)), started)
            except SceneSuggestError as e:
                self._send(400, {"error": e.message, "field": e.field}, started)
            except orjson.JSONDecodeError:
                self._send(400, {"error": "not JSON"}, started)

        def _send(self, status: int, doc: dict, started: float | None = None) -> None:
            """The answer, with the engine's own time (from the query read to the answer written) as
            Server-Timing, so that a client can tell it from the transport's."""
            started = time.perf_counter() if started is None else started
            body = orjson.dumps(doc, option=orjson.OPT_SERIALIZE_NUMPY)
            self.send_response(status)
            self.send_header("Content-Type", "application/json")
            self.send_header("Content-Length", str(len(body)))
            self.send_header("Server-Timing", f"engine;dur={(time.perf_counter() - started) * 1000:.3f}")
            self.end_headers()
            self.wfile.write(body)

        def log_message(self, format, *args):  # noqa: A002 - quiet: one line per query is noise
            pass

    server = ThreadingHTTPServer((host, port), Handler)
    server.daemon_threads = True
    return server
