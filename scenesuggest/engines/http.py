"""The ``http`` engine: an engine in any language behind HTTP, with a fallback that always answers.

For each query the server POSTs one JSON document (:func:`query_document`; its JSON Schema is
:data:`QUERY_SCHEMA`, published in the API's OpenAPI document) to the engine's ``url`` and reads one JSON answer
(:data:`ANSWER_SCHEMA`), which is validated strictly (:func:`parse_answer`): at most ``max_suggestions``
suggestions of categories the query allows, each once, finite scores, rigid 4×4 placements (16 numbers,
column-major, canonical → world, within 100 m of the click), faces and model ids the study knows, and at most
``max_bytes`` bytes. A timeout (``timeout_ms``, the whole exchange: connecting, sending, waiting and reading), a
refused connection, a status other than 200, a body that is not JSON or an answer that breaks a rule gives the
fallback engine's list instead, with the reason (:attr:`~scenesuggest.suggest.SuggestionList.fallback`): the
participant never waits longer than the timeout for a list and never sees an error because of the engine.

Connections are kept alive (one per thread) and made afresh after any failure.
"""

from __future__ import annotations

import contextlib
import http.client
import ipaddress
import math
import select
import socket
import ssl
import threading
import time
from collections.abc import Collection, Mapping
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any
from urllib.parse import urlsplit

import numpy as np
import orjson

from .. import frames, poses
from ..errors import SceneSuggestError
from ..query import ContextQuery, prepare
from ..scene_json import finite, scene_to_dict
from ..suggest import MODES, Suggestion, SuggestionList
from ..taxonomy import Taxonomy
from .protocol import EngineKind, LoadContext, SuggestionEngine

PROTOCOL_VERSION = 1
DEFAULT_TIMEOUT_MS = 300
#: The longest a participant may wait for the engine (each sync server worker waits as long).
MAX_TIMEOUT_MS = 2_000
DEFAULT_MAX_SUGGESTIONS = 40
DEFAULT_MAX_BYTES = 1 << 20
#: A placement's rotation must be orthonormal to this tolerance, and its origin this close to the click (metres).
RIGID_TOLERANCE = 1e-4
MAX_DISTANCE_M = 100.0
MAX_TERMS = 16
MAX_MODELS = 64
MAX_TEXT = 200
OPTIONS = ("url", "timeout_ms", "fallback", "max_suggestions", "max_bytes")

_NUMBER = {"type": "number"}
_VEC3 = {"type": "array", "items": _NUMBER, "minItems": 3, "maxItems": 3}
QUERY_SCHEMA = {
    "type": "object", "title": "EngineQuery",
    "description": "What the study server POSTs to an HTTP engine for one click (metres, world frame, +Y up).",
    "required": ["protocol", "scene", "parent", "point", "normal", "surface_type", "scene_type", "mode", "top",
                 "categories"],
    "properties": {
        "protocol": {"const": PROTOCOL_VERSION},
        "scene": {"type": "object", "description": "the participant's scene in the native scene format "
                                                   "(scenesuggest-scene, version 1)"},
        "parent": {"type": "string", "description": "id of the clicked object"},
        "point": {**_VEC3, "description": "the clicked point"},
        "normal": {**_VEC3, "description": "the unit surface normal there"},
        "surface_type": {"type": "string", "enum": ["up_interior", "up_exterior", "down_interior", "down_exterior",
                                                    "vertical_interior", "vertical_exterior"]},
        "scene_type": {"type": "string"},
        "mode": {"type": "string", "enum": list(MODES),
                 "description": "basic: canonical pose; full: also oriented"},
        "top": {"type": "integer", "minimum": 1, "description": "at most this many suggestions are read"},
        "categories": {"type": "array", "items": {"type": "string"},
                       "description": "the categories the answer may hold (those the study's library can place)"},
    },
}
ANSWER_SCHEMA = {
    "type": "object", "title": "EngineAnswer", "required": ["suggestions"],
    "description": "An HTTP engine's answer: suggestions, best first.",
    "properties": {"suggestions": {"type": "array", "items": {
        "type": "object", "required": ["category", "score", "placement"],
        "properties": {
            "category": {"type": "string", "description": "one of the query's categories, at most once"},
            "score": {**_NUMBER, "description": "finite; higher is better"},
            "placement": {"type": "array", "items": _NUMBER, "minItems": 16, "maxItems": 16,
                          "description": "rigid 4×4 canonical → world transform, column-major"},
            "attachment_face": {"type": "string", "enum": list(frames.FACES)},
            "heading_deg": _NUMBER,
            "models": {"type": "array", "items": {"type": "string"}, "maxItems": MAX_MODELS,
                       "description": "model ids of the category, best first (default: the category's models)"},
            "terms": {"type": "object", "additionalProperties": _NUMBER, "maxProperties": MAX_TERMS,
                      "description": "why the category got its rank (name → number)"},
        }}}},
}


class EngineUnavailable(Exception):
    """The external engine gave no usable answer; ``str()`` is the reason, without the URL."""


@dataclass(frozen=True)
class HttpOptions:
    url: str
    timeout_ms: int = DEFAULT_TIMEOUT_MS
    fallback: Any = None  # the fallback's EngineSpec
    max_suggestions: int = DEFAULT_MAX_SUGGESTIONS
    max_bytes: int = DEFAULT_MAX_BYTES


def _integer(options: Mapping, key: str, default: int, low: int, high: int) -> int:
    value = options.get(key, default)
    if isinstance(value, bool) or not isinstance(value, int) or not low <= value <= high:
        raise SceneSuggestError(f"expected an integer from {low} to {high}", field=key)
    return value


def _url(value) -> str:
    if not isinstance(value, str) or not value:
        raise SceneSuggestError("missing: the engine's http(s) URL", field="url")
    if any(ord(c) <= 32 or ord(c) == 127 for c in value):
        raise SceneSuggestError("expected a URL without spaces or control characters", field="url")
    parts = urlsplit(value)
    if parts.scheme not in ("http", "https") or not parts.hostname or parts.username or parts.password:
        raise SceneSuggestError("expected an http:// or https:// URL with a host and no credentials", field="url")
    try:
        _ = parts.port
    except ValueError:
        raise SceneSuggestError("the URL's port is not a number from 0 to 65535", field="url") from None
    return value


class HttpKind(EngineKind):
    name = "http"
    version = "1"
    summary = "an engine in any language behind HTTP (JSON), with a fallback engine for timeouts and bad answers"

    def configure(self, options: Mapping[str, Any], base: Path | None = None) -> HttpOptions:
        from . import configure

        for key in options:
            if key not in OPTIONS:
                raise SceneSuggestError(f"unknown key: this engine takes name, {', '.join(OPTIONS)}", field=key)
        fallback = options.get("fallback", "paper")
        table = {"name": fallback} if isinstance(fallback, str) else fallback
        if not isinstance(table, Mapping) or table.get("name", "paper") == self.name:
            raise SceneSuggestError("expected the name (or table) of an engine other than http", field="fallback")
        try:
            spec = configure(table, base)
        except SceneSuggestError as e:
            raise SceneSuggestError(e.message, field="fallback" + (f".{e.field}" if e.field else "")) from None
        return HttpOptions(_url(options.get("url")), _integer(options, "timeout_ms", DEFAULT_TIMEOUT_MS, 1,
                                                              MAX_TIMEOUT_MS), spec,
                           _integer(options, "max_suggestions", DEFAULT_MAX_SUGGESTIONS, 1, 1000),
                           _integer(options, "max_bytes", DEFAULT_MAX_BYTES, 1024, 64 << 20))

    def trained_file(self, config: HttpOptions, priors: Path) -> Path | None:
        return config.fallback.kind.trained_file(config.fallback.config, priors)

    def load(self, config: HttpOptions, context: LoadContext) -> HttpEngine:
        from . import load

        fallback = context.load(config.fallback) if context.load is not None else load(config.fallback, context)
        return HttpEngine(config, fallback)


def query_document(prep, mode: str, top: int, categories: Collection[str]) -> dict:
    """The JSON document POSTed for a prepared query (:data:`QUERY_SCHEMA`)."""
    return {"protocol": PROTOCOL_VERSION, "scene": scene_to_dict(prep.query.scene), "parent": prep.query.parent_id,
            "point": [float(x) for x in prep.point], "normal": [float(x) for x in prep.normal],
            "surface_type": prep.surface_type, "scene_type": prep.scene_type, "mode": mode, "top": int(top),
            "categories": sorted(categories)}


def _placements(items: list, point: np.ndarray) -> np.ndarray:
    """(n, 4, 4) placements of the answer's items, checked: 16 finite numbers each, rigid, near the click."""
    numbers = (int, float)  # JSON numbers as the parser gives them (not booleans, strings or nulls)
    for i, item in enumerate(items):
        value = item.get("placement")
        if not isinstance(value, list) or len(value) != 16 or not all(type(v) in numbers for v in value):
            raise EngineUnavailable(f"invalid answer: suggestions[{i}].placement is not 16 finite numbers")
    m = np.array([item["placement"] for item in items], dtype=float).reshape(-1, 4, 4).transpose(0, 2, 1)
    if not np.isfinite(m).all():
        raise EngineUnavailable("invalid answer: a placement is not 16 finite numbers")
    r = m[:, :3, :3]
    bad = ((np.abs(m[:, 3] - [0, 0, 0, 1]).max(axis=1) > RIGID_TOLERANCE)
           | (np.abs(np.einsum("nji,njk->nik", r, r) - np.eye(3)).max(axis=(1, 2)) > RIGID_TOLERANCE)
           | (np.linalg.det(r) <= 0)) if len(m) else np.zeros(0, dtype=bool)
    if bad.any():
        raise EngineUnavailable(f"invalid answer: suggestions[{int(np.argmax(bad))}].placement is not a rigid "
                                "transform")
    far = np.linalg.norm(m[:, :3, 3] - point, axis=1) > MAX_DISTANCE_M if len(m) else np.zeros(0, dtype=bool)
    if far.any():
        raise EngineUnavailable(f"invalid answer: suggestions[{int(np.argmax(far))}].placement is more than "
                                f"{MAX_DISTANCE_M:g} m from the click")
    return m


def parse_answer(doc, allowed: Collection[str], models: Mapping[str, tuple[str, ...]], point, normal,
                 max_suggestions: int) -> list[Suggestion]:
    """The suggestions of an answer document, checked by the rules of the module docstring; raises
    :class:`EngineUnavailable` naming the first broken rule (``suggestions[3].placement: …``)."""
    if not isinstance(doc, dict) or not isinstance(doc.get("suggestions"), list):
        raise EngineUnavailable("invalid answer: expected {\"suggestions\": [...]}")
    items = doc["suggestions"]
    if len(items) > max_suggestions:
        raise EngineUnavailable(f"invalid answer: {len(items)} suggestions, at most {max_suggestions}")
    for i, item in enumerate(items):
        if not isinstance(item, dict):
            raise EngineUnavailable(f"invalid answer: suggestions[{i}] is not an object")
    placements = _placements(items, np.asarray(point, dtype=float))
    out, seen = [], set()
    for i, (item, placement) in enumerate(zip(items, placements, strict=True)):
        where = f"suggestions[{i}]"
        category = item.get("category")
        if not isinstance(category, str) or category not in allowed:
            raise EngineUnavailable(f"invalid answer: {where}.category is not one the query allows")
        if category in seen:
            raise EngineUnavailable(f"invalid answer: {where}.category appears twice")
        seen.add(category)
        if not finite(item.get("score")):
            raise EngineUnavailable(f"invalid answer: {where}.score is not a finite number")
        touching = frames.face_of_direction(placement[:3, :3].T @ -np.asarray(normal, dtype=float))
        face = item.get("attachment_face", touching)
        if face not in frames.FACES:
            raise EngineUnavailable(f"invalid answer: {where}.attachment_face is not one of {', '.join(frames.FACES)}")
        if face != touching:
            raise EngineUnavailable(f"invalid answer: {where}.attachment_face is not the face its placement turns to "
                                    "the clicked surface")
        heading = item.get("heading_deg")
        if heading is None:
            heading = math.degrees(float(poses.wrap(poses.object_heading(placement, face, normal))))
        if not finite(heading):
            raise EngineUnavailable(f"invalid answer: {where}.heading_deg is not a finite number (nor follows from "
                                    "the placement)")
        known = models.get(category, ())
        chosen = item.get("models", list(known[:MAX_MODELS]))
        if not isinstance(chosen, list) or len(chosen) > MAX_MODELS:
            raise EngineUnavailable(f"invalid answer: {where}.models is not a list of at most {MAX_MODELS} ids")
        if not all(isinstance(m, str) for m in chosen) or not set(chosen) <= set(known):
            raise EngineUnavailable(f"invalid answer: {where}.models are not models of {category!r}")
        terms = item.get("terms", {})
        if (not isinstance(terms, dict) or len(terms) > MAX_TERMS
                or not all(isinstance(k, str) and len(k) <= MAX_TEXT and finite(v) for k, v in terms.items())):
            raise EngineUnavailable(f"invalid answer: {where}.terms must map at most {MAX_TERMS} names to numbers")
        out.append(Suggestion(rank=i + 1, category=category, score=float(item["score"]),
                              terms={k: float(v) for k, v in terms.items()}, placement=placement,
                              attachment_face=face, heading_deg=float(heading), models=tuple(chosen) or known))
    return out


class _Watchdog:
    """Ends exchanges that pass their deadline, however the engine dribbles its bytes: one thread per engine
    sleeps until the nearest deadline and shuts that exchange's socket (a timer thread per request cost 1 ms);
    it ends after a minute with nothing to watch and starts again when needed."""

    IDLE_S = 60.0

    def __init__(self):
        self._due: dict[int, tuple[float, socket.socket]] = {}
        self._wake = threading.Condition()
        self._thread: threading.Thread | None = None

    def arm(self, key: int, deadline: float, sock: socket.socket) -> None:
        with self._wake:
            self._due[key] = (deadline, sock)
            if self._thread is None:
                self._thread = threading.Thread(target=self._run, name="http-engine-watchdog", daemon=True)
                self._thread.start()
            self._wake.notify()

    def disarm(self, key: int) -> bool:
        """Whether the exchange was still armed (False: its socket was shut, or it never was armed)."""
        with self._wake:
            return self._due.pop(key, None) is not None

    def _run(self) -> None:
        with self._wake:
            while True:
                now = time.monotonic()
                for key, (deadline, sock) in list(self._due.items()):
                    if deadline <= now:
                        del self._due[key]
                        with contextlib.suppress(OSError):  # the plain socket's: a TLS socket's own would unwrap it
                            socket.socket.shutdown(sock, socket.SHUT_RDWR)
                if not self._due:
                    self._wake.wait(self.IDLE_S)
                    if not self._due:
                        self._thread = None
                        return
                    continue
                self._wake.wait(max(min(d for d, _ in self._due.values()) - now, 0.001))


class _Connection(threading.local):
    conn: http.client.HTTPConnection | None = None
    #: The engine's own time for the last answer on this thread (its Server-Timing header), None if unsaid.
    server_ms: float | None = None


def _server_ms(header: str | None) -> float | None:
    """The sum of the ``dur`` (milliseconds) of a Server-Timing header's metrics, None without any."""
    durations = []
    for metric in (header or "").split(","):
        for param in metric.split(";")[1:]:
            key, _, value = param.strip().partition("=")
            if key == "dur":
                with contextlib.suppress(ValueError):
                    durations.append(float(value))
    return sum(durations) if durations else None


class HttpEngine:
    """Posts each query to the external engine; answers with the fallback engine's list (and the reason) when
    the external one fails (see the module docstring)."""

    name = "http"

    def __init__(self, options: HttpOptions, fallback: SuggestionEngine):
        self.options = options
        self.fallback = fallback
        self.taxonomy = getattr(getattr(fallback, "priors", None), "taxonomy", None) or Taxonomy()
        parts = urlsplit(options.url)
        self._tls = ssl.create_default_context() if parts.scheme == "https" else None
        self._host, self._port = parts.hostname, parts.port or (443 if self._tls else 80)
        self._path = (parts.path or "/") + (f"?{parts.query}" if parts.query else "")
        self._local = _Connection()
        self._watchdog = _Watchdog()
        #: Answers replaced by the fallback's in this process (what /healthz reports).
        self.fallbacks = 0
        self._count = threading.Lock()

    @property
    def categories(self) -> Mapping[str, tuple[str, ...]]:
        return self.fallback.categories

    def suggest(self, query: ContextQuery, mode: str = "full", top: int | None = None,
                only: Collection[str] | None = None) -> SuggestionList:
        if mode not in MODES:
            raise SceneSuggestError(f"mode must be one of {', '.join(MODES)}", field="mode")
        if top is not None and (isinstance(top, bool) or not isinstance(top, int) or top < 1):
            raise SceneSuggestError("top must be a positive integer", field="top")
        prep = prepare(query, self.taxonomy)  # a query the engine cannot be asked is the participant's 400
        allowed = set(self.categories) if only is None else set(only) & set(self.categories)
        limit = min(top or self.options.max_suggestions, self.options.max_suggestions)
        try:
            body = orjson.dumps(query_document(prep, mode, limit, allowed), option=orjson.OPT_SERIALIZE_NUMPY)
            try:
                doc = orjson.loads(self._exchange(body))
            except orjson.JSONDecodeError:  # NaN, Infinity and 1e999 are not JSON either
                raise EngineUnavailable("invalid answer: not JSON") from None
            found = parse_answer(doc, allowed, self.categories, prep.point, prep.normal, self.options.max_suggestions)
        except EngineUnavailable as e:
            with self._count:
                self.fallbacks += 1
            return replace(self.fallback.suggest(query, mode, top, only), fallback=str(e))
        return SuggestionList(tuple(found[:top] if top else found), prep.surface_type, prep.scene_type,
                              prep.parent_category, engine=self.name)

    def last_server_ms(self) -> float | None:
        """What the engine said (Server-Timing) its last answer on this thread took, in milliseconds (None: it
        said nothing, or there was no answer)."""
        return self._local.server_ms

    def close(self) -> None:
        """Close this thread's connection (the next query opens a new one)."""
        if self._local.conn is not None:
            self._local.conn.close()
            self._local.conn = None

    # --- the exchange ----------------------------------------------------------------------------------------
    def _exchange(self, body: bytes) -> bytes:
        """POST ``body``; the answer's bytes. Everything within the timeout, or :class:`EngineUnavailable`.

        A kept-alive connection that the engine closed while it was idle (servers do after a few seconds) is
        noticed before it is used, or when it fails before the first byte of an answer, and the query is sent
        once more on a new connection if time remains."""
        deadline = time.monotonic() + self.options.timeout_ms / 1000
        self._local.server_ms = None
        key = threading.get_ident()
        try:
            try:
                return self._post(body, deadline, key)
            except _Stale:
                self.close()
                return self._post(body, deadline, key)
        except EngineUnavailable:
            self.close()
            raise
        except Exception as e:  # noqa: BLE001 - whatever the engine does, the participant gets the fallback's list
            self.close()
            if time.monotonic() >= deadline - 1e-3:
                raise EngineUnavailable(f"no answer within {self.options.timeout_ms} ms") from None
            cause = e.__cause__ if isinstance(e, _Stale) and e.__cause__ else e
            raise EngineUnavailable(f"connection failed ({type(cause).__name__})") from None
        finally:
            if not self._watchdog.disarm(key):  # shut at the deadline (or never armed): not to be used again
                self.close()

    def _remaining(self, deadline: float) -> float:
        left = deadline - time.monotonic()
        if left <= 0:
            raise EngineUnavailable(f"no answer within {self.options.timeout_ms} ms")
        return left

    def _open(self, deadline: float, key: int) -> http.client.HTTPConnection:
        """A new connection, made within the deadline: the name resolved, connected, TLS shaken hands — each
        step watched, so that no step can outlast the timeout."""
        last: Exception | None = None
        for family, kind, proto, _, address in _resolve(self._host, self._port, self._remaining(deadline)):
            sock = socket.socket(family, kind, proto)
            self._watchdog.arm(key, deadline, sock)
            try:
                sock.settimeout(self._remaining(deadline))
                sock.connect(address)
                break
            except OSError as e:
                last = e
                sock.close()
        else:
            raise last or OSError("the engine's host has no address")
        sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        if self._tls is not None:
            sock = self._tls.wrap_socket(sock, server_hostname=self._host, do_handshake_on_connect=False)
            self._watchdog.arm(key, deadline, sock)
            sock.settimeout(self._remaining(deadline))
            sock.do_handshake()
        conn = http.client.HTTPConnection(self._host, self._port)
        conn.sock = sock
        return conn

    def _post(self, body: bytes, deadline: float, key: int) -> bytes:
        conn = self._local.conn
        if conn is not None and _closed_by_peer(conn.sock):
            self.close()
            conn = None
        reused = conn is not None
        if conn is None:
            conn = self._local.conn = self._open(deadline, key)
        else:
            self._watchdog.arm(key, deadline, conn.sock)
        sock = conn.sock  # the connection lets go of it when the engine says it will close: the answer still reads it
        sock.settimeout(self._remaining(deadline))
        try:
            conn.request("POST", self._path, body, {"Content-Type": "application/json", "Accept": "application/json"})
            response = conn.getresponse()
        except (ConnectionError, http.client.BadStatusLine) as e:
            if reused and time.monotonic() < deadline:
                raise _Stale() from e
            raise
        try:
            return self._read(response, sock, deadline)
        finally:
            response.close()  # whatever happened: the socket the answer holds is not left to the collector

    def _read(self, response: http.client.HTTPResponse, sock, deadline: float) -> bytes:
        """The answer's body, at most ``max_bytes``, within the deadline."""
        self._local.server_ms = _server_ms(response.getheader("Server-Timing"))
        if response.status != 200:
            raise EngineUnavailable(f"HTTP {response.status}")
        cap = self.options.max_bytes
        length = response.getheader("Content-Length")
        if length is not None and (not (length.isascii() and length.isdigit()) or int(length) > cap):
            raise EngineUnavailable(f"answer larger than {cap} bytes")
        chunks, size = [], 0
        while True:
            sock.settimeout(self._remaining(deadline))
            chunk = response.read(min(65536, cap + 1 - size))  # read, not read1: it ends the response
            if not chunk:
                break
            chunks.append(chunk)
            size += len(chunk)
            if size > cap:
                raise EngineUnavailable(f"answer larger than {cap} bytes")
        self._remaining(deadline)
        if response.will_close:
            self.close()
        return b"".join(chunks)


class _Stale(Exception):
    """A kept-alive connection failed before the first byte of an answer: the engine had closed it."""


def _closed_by_peer(sock) -> bool:
    """Whether an idle kept-alive connection has something to read — the engine's close (or bytes it should not
    have sent): either way it cannot carry the next query."""
    try:
        readable, _, _ = select.select([sock], [], [], 0)
    except (OSError, ValueError):
        return True
    return bool(readable)


def _resolve(host: str, port: int, timeout: float) -> list:
    """getaddrinfo within ``timeout`` seconds (name lookups have no timeout of their own); an IP address at once."""
    try:
        ipaddress.ip_address(host)
        return socket.getaddrinfo(host, port, type=socket.SOCK_STREAM)
    except ValueError:
        pass
    found: list = []
    failed: list[Exception] = []

    def look_up() -> None:
        try:
            found.extend(socket.getaddrinfo(host, port, type=socket.SOCK_STREAM))
        except OSError as e:
            failed.append(e)

    thread = threading.Thread(target=look_up, name="http-engine-resolve", daemon=True)
    thread.start()
    thread.join(timeout)
    if thread.is_alive():
        raise TimeoutError("the engine's name did not resolve in time")
    if failed:
        raise failed[0]
    return found


KIND = HttpKind()
