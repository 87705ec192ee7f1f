"""The ``http`` engine: an engine in any language behind HTTP, with a fallback that always answers.

For each query the server POSTs one JSON document (:func:`.wire.query_document`; its JSON Schema is
:data:`.wire.QUERY_SCHEMA`, published in the API's OpenAPI document) to the engine's ``url`` and reads one JSON
answer (:data:`.wire.ANSWER_SCHEMA`), which is validated strictly (:func:`.wire.parse_answer`): at most
``max_suggestions`` suggestions of categories the query allows, each once, finite scores, rigid 4×4 placements
(16 numbers, column-major, canonical → world, within 100 m of the click), attachment faces that the placements turn
to the surface, finite headings, model ids the study knows, and at most ``max_bytes`` bytes. A timeout
(``timeout_ms``, the whole exchange: name lookup, connecting, the TLS handshake, sending, waiting and reading), a
refused connection, a status other than 200, a body that is not JSON or an answer that breaks a rule gives the
fallback engine's list instead, with the reason (:attr:`~scenesuggest.suggestion.suggest.SuggestionList.fallback`): the
participant never waits longer than the timeout (and the fallback's own time) for a list and never sees an error
because of the engine.

The exchange is urllib3's (kept-alive connections in a pool, made afresh after any failure and when the engine has
closed one while it was idle; any HTTP/1.0 or 1.1 answer, whether or not the connection stays open); this module
adds only what it does not do: a deadline for the whole exchange (the name looked up in a thread, since a lookup
has no timeout of its own, and a watchdog that shuts a connection at the deadline however the engine dribbles its
bytes), and a cap on the answer's size.

A slow or failing engine never slows anyone else: the query carries at most ``wire.MAX_QUERY_OBJECTS`` objects of
the participant's scene (:func:`.wire.query_scene`), so a participant cannot make it slow; a circuit breaker
(:class:`Breaker`) falls back at once while the engine keeps failing and tries it again now and then; and a
server's workers share :class:`WaitSlots`, so that at most half of them wait on engines at once.
"""

from __future__ import annotations

import contextlib
import ipaddress
import math
import socket
import ssl
import threading
import time
from collections.abc import Collection, Mapping
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any
from urllib.parse import urlsplit

import orjson
import urllib3

from ..errors import SceneSuggestError
from ..scenes.taxonomy import Taxonomy
from ..suggestion.query import ContextQuery, prepare
from ..suggestion.suggest import MODES, SuggestionList
from .protocol import EngineKind, LoadContext, SuggestionEngine, WaitSlots
from .wire import ANSWER_SCHEMA, QUERY_SCHEMA, NoUsableAnswer, parse_answer, query_document

DEFAULT_TIMEOUT_MS = 300
#: The longest a participant may wait for the engine (each sync server worker waits as long).
MAX_TIMEOUT_MS = 2_000
DEFAULT_MAX_SUGGESTIONS = 40
DEFAULT_MAX_BYTES = 1 << 20
OPTIONS = ("url", "timeout_ms", "fallback", "max_suggestions", "max_bytes")

__all__ = ["ANSWER_SCHEMA", "Breaker", "NoUsableAnswer", "HttpEngine", "KIND", "QUERY_SCHEMA", "WaitSlots",
           "parse_answer"]


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


#: The circuit breaker (:class:`Breaker`): failures in a row that open it, how long it stays open at first
#: (seconds; each failed probe doubles it, up to BREAKER_MAX_S).
BREAKER_FAILURES = 3
BREAKER_OPEN_S = 10.0
BREAKER_MAX_S = 300.0


class Breaker:
    """While the engine is failing, queries stop paying its timeout: after BREAKER_FAILURES failures in a row (a
    timeout, a refused connection, an error status, an answer that breaks a rule) the circuit opens and every
    query gets the fallback's list at once; after BREAKER_OPEN_S seconds one query (the first to come) probes the
    engine while the others still fall back; an answer closes the circuit, a failure opens it again for twice as
    long (up to BREAKER_MAX_S). ``on_change(state, detail)`` hears each opening (``"open"``: the last reason, the
    failures, the seconds until the next probe) and closing (``"closed"``). One per engine and process; thread-safe.
    """

    def __init__(self, on_change=None, clock=time.monotonic):
        self.on_change = on_change
        self._clock = clock
        self._lock = threading.Lock()
        self.failures = 0
        self.state = "closed"  # closed | open | probing
        self._until = 0.0
        self._open_s = BREAKER_OPEN_S

    def refusal(self) -> str | None:
        """None when a query may go to the engine now (the circuit is closed, or this query is the probe); else
        why it falls back at once."""
        with self._lock:
            if self.state == "closed":
                return None
            now = self._clock()
            if self.state == "open" and now >= self._until:
                self.state = "probing"
                return None
            wait = max(0.0, self._until - now)
            return (f"the engine failed {self.failures} times in a row: not asked for {wait:.0f} s more"
                    if self.state == "open" else "the engine failed: another query is trying it again")

    def record(self, failure: str | None) -> None:
        """The outcome of a query sent to the engine: None for an answer, else why it failed."""
        with self._lock:
            if failure is None:
                changed = self.state != "closed"
                self.failures, self.state, self._open_s = 0, "closed", BREAKER_OPEN_S
                event = ("closed", {}) if changed else None
            else:
                self.failures += 1
                event = None
                if self.state == "probing" or self.failures >= BREAKER_FAILURES:
                    if self.state == "probing":
                        self._open_s = min(2 * self._open_s, BREAKER_MAX_S)
                    self.state, self._until = "open", self._clock() + self._open_s
                    event = ("open", {"reason": failure, "failures": self.failures, "retry_s": self._open_s})
        if event is not None and self.on_change is not None:
            self.on_change(*event)


class _Watchdog:
    """Ends exchanges that pass their deadline, however the engine dribbles its bytes: one thread per engine
    sleeps until the nearest deadline and shuts that exchange's socket (a timer thread per request cost 1 ms).
    Arming wakes it only when the new deadline comes before its own waking time, so that queries one after
    another (each deadline later than the last) do not wake it at all. It ends after a minute with nothing to
    watch and starts again when needed."""

    IDLE_S = 60.0

    def __init__(self):
        self._due: dict[int, tuple[float, socket.socket]] = {}
        self._wake = threading.Condition()
        self._thread: threading.Thread | None = None
        #: When the thread next wakes by itself (monotonic seconds).
        self._waking = math.inf

    def arm(self, key: int, deadline: float, sock: socket.socket) -> None:
        with self._wake:
            self._due[key] = (deadline, sock)
            if self._thread is None:
                self._thread = threading.Thread(target=self._run, name="http-engine-watchdog", daemon=True)
                self._thread.start()
            elif deadline < self._waking:  # woken only to come sooner: one query after another leaves it asleep
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
                    self._waking = now + self.IDLE_S
                    self._wake.wait(self.IDLE_S)
                    if not self._due:
                        self._thread, self._waking = None, math.inf
                        return
                    continue
                wait = max(min(d for d, _ in self._due.values()) - now, 0.001)
                self._waking = now + wait
                self._wake.wait(wait)


class _Exchange(threading.local):
    """This thread's exchange in progress: its deadline (monotonic seconds) and watchdog key; and the engine's own
    time for the last answer on this thread (its Server-Timing header), None if unsaid."""

    deadline: float = 0.0
    key: int = 0
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
        self._local = _Exchange()
        self._watchdog = _Watchdog()
        self._pool: urllib3.HTTPConnectionPool | None = None
        self._pool_lock = threading.Lock()
        #: Answers replaced by the fallback's in this process (what /healthz reports).
        self.fallbacks = 0
        self.breaker = Breaker()
        #: Shared with the server's other workers (:class:`WaitSlots`); None: no bound (one process).
        self.slots: WaitSlots | None = None
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
            with self.slots.held() if self.slots is not None else contextlib.nullcontext(True) as free:
                if not free:  # asked before the breaker: a query that never reaches the engine never probes it
                    raise NoUsableAnswer(f"the engine is busy: {self.slots.count} queries of this server "
                                            "already wait on engines")
                refused = self.breaker.refusal()
                if refused is not None:
                    raise NoUsableAnswer(refused)
                outcome = "the query never reached the engine"  # until it has an outcome (a probe then ends)
                try:
                    body = orjson.dumps(query_document(prep, mode, limit, allowed),
                                        option=orjson.OPT_SERIALIZE_NUMPY)  # only for a query the engine gets
                    try:
                        doc = orjson.loads(self._exchange(body))
                    except orjson.JSONDecodeError:  # NaN, Infinity and 1e999 are not JSON either
                        raise NoUsableAnswer("invalid answer: not JSON") from None
                    found = parse_answer(doc, allowed, self.categories, prep.point, prep.normal,
                                         self.options.max_suggestions)
                    outcome = None
                except NoUsableAnswer as e:
                    outcome = str(e)
                    raise
                finally:
                    self.breaker.record(outcome)
        except NoUsableAnswer as e:
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
        """Close every connection to the engine (the next query opens a new one)."""
        with self._pool_lock:
            pool, self._pool = self._pool, None
        if pool is not None:
            pool.close()

    # --- the exchange ----------------------------------------------------------------------------------------
    def _connections(self) -> urllib3.HTTPConnectionPool:
        """The pool of kept-alive connections (urllib3: any HTTP/1.0 or 1.1 answer, a connection the engine closed
        noticed before it is used again), its connections made by :meth:`_connect`."""
        with self._pool_lock:
            if self._pool is None:
                engine = self
                base = urllib3.connection.HTTPSConnection if self._tls else urllib3.connection.HTTPConnection

                class Watched(base):  # the name resolved, connected and watched within this exchange's deadline
                    def _new_conn(self):
                        return engine._connect()

                    def request(self, *args, **kwargs):
                        if self.sock is not None:  # a kept-alive connection: watched from now on
                            engine._watchdog.arm(engine._local.key, engine._local.deadline, self.sock)
                        return super().request(*args, **kwargs)

                kind = urllib3.HTTPSConnectionPool if self._tls else urllib3.HTTPConnectionPool
                extra = {"ssl_context": self._tls} if self._tls else {}
                self._pool = kind(self._host, self._port, maxsize=8, block=False, retries=False, **extra)
                self._pool.ConnectionCls = Watched
            return self._pool

    def _exchange(self, body: bytes) -> bytes:
        """POST ``body``; the answer's bytes. Everything within the timeout (urllib3's timeouts bound each step;
        the watchdog shuts a connection at the deadline however the engine dribbles its bytes), or
        :class:`NoUsableAnswer`."""
        local = self._local
        local.deadline, local.key = time.monotonic() + self.options.timeout_ms / 1000, threading.get_ident()
        local.server_ms = None
        response = None
        try:
            left = self._remaining()
            response = self._connections().urlopen(
                "POST", self._path, body=body, headers={"Content-Type": "application/json",
                                                        "Accept": "application/json"},
                retries=False, redirect=False, preload_content=False, release_conn=False,
                timeout=urllib3.Timeout(connect=left, read=left))
            answer = self._read(response)
            if self._watchdog.disarm(local.key):  # read whole, its socket never shut: it may carry the next query
                response.release_conn()
            else:
                self._discard(response)
            return answer
        except NoUsableAnswer:
            self._watchdog.disarm(local.key)
            self._discard(response)
            raise
        except Exception as e:  # noqa: BLE001 - whatever the engine does, the participant gets the fallback's list
            self._watchdog.disarm(local.key)
            self._discard(response)
            if time.monotonic() >= local.deadline - 1e-3 or isinstance(e, urllib3.exceptions.TimeoutError):
                raise NoUsableAnswer(f"no answer within {self.options.timeout_ms} ms") from None
            cause = getattr(e, "reason", None) or e
            raise NoUsableAnswer(f"connection failed ({type(cause).__name__})") from None

    def _discard(self, response) -> None:
        """After a failure: the answer's connection closed, never reused."""
        if response is not None:
            response.close()
            if response.connection is not None:
                response.connection.close()
            response.release_conn()

    def _remaining(self) -> float:
        left = self._local.deadline - time.monotonic()
        if left <= 0:
            raise NoUsableAnswer(f"no answer within {self.options.timeout_ms} ms")
        return left

    def _connect(self) -> socket.socket:
        """A new connection's socket, made within the deadline: the name resolved (in a thread: a lookup has no
        timeout of its own) and connected, watched while it connects. The TLS handshake that urllib3 does next is
        bounded by the socket's timeout (the time left; Python bounds a whole handshake by it); the request and
        the answer are watched again (:meth:`_connections`)."""
        last: Exception | None = None
        for family, kind, proto, _, address in _resolve(self._host, self._port, self._remaining()):
            sock = socket.socket(family, kind, proto)
            self._watchdog.arm(self._local.key, self._local.deadline, sock)
            try:
                sock.settimeout(self._remaining())
                sock.connect(address)
                sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
                return sock
            except OSError as e:
                last = e
                sock.close()
            except BaseException:  # out of time: no socket left behind
                sock.close()
                raise
        raise last or OSError("the engine's host has no address")

    def _read(self, response) -> bytes:
        """The answer's body, at most ``max_bytes``, within the deadline."""
        self._local.server_ms = _server_ms(response.headers.get("Server-Timing"))
        if response.status != 200:
            raise NoUsableAnswer(f"HTTP {response.status}")
        cap = self.options.max_bytes
        length = response.headers.get("Content-Length")
        if length is not None and (not (length.isascii() and length.isdigit()) or int(length) > cap):
            raise NoUsableAnswer(f"answer larger than {cap} bytes")
        chunks, size = [], 0
        for chunk in response.stream(65536, decode_content=False):
            chunks.append(chunk)
            size += len(chunk)
            if size > cap:
                raise NoUsableAnswer(f"answer larger than {cap} bytes")
            self._remaining()
        self._remaining()
        return b"".join(chunks)


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
