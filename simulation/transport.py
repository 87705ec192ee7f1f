"""How a simulated participant reaches the server: a Flask test client in process, or real HTTP.

Every transport follows redirects (as a browser does) and answers a :class:`Response`. Nothing here knows the
study's pages or API; :mod:`.walker` and :mod:`.participant` do.
"""

from __future__ import annotations

import http.client
import http.cookiejar
import json
import time
import urllib.error
import urllib.request
from dataclasses import dataclass
from urllib.parse import urlencode, urlsplit

import numpy as np


class FlowError(RuntimeError):
    """The server answered something a participant's browser would not have expected (``status``: its HTTP
    status, when it answered)."""

    def __init__(self, message: str, status: int | None = None):
        super().__init__(message)
        self.status = status


@dataclass
class Response:
    status: int
    body: bytes

    @property
    def text(self) -> str:
        return self.body.decode(errors="replace")

    def json(self):
        return json.loads(self.body)


class FlaskTransport:
    """Requests through a Flask test client (in process; cookies kept by the client)."""

    def __init__(self, client):
        self.client = client

    def get(self, path, headers=None) -> Response:
        r = self.client.get(path, headers=headers or {}, follow_redirects=True)
        return Response(r.status_code, r.get_data())

    def post(self, path, form=None, json_body=None, headers=None) -> Response:
        r = self.client.post(path, data=form, json=json_body, headers=headers or {}, follow_redirects=True)
        return Response(r.status_code, r.get_data())


class HttpTransport:
    """Real HTTP to a running server (urllib, a cookie jar per participant, redirects followed).

    Like the browser's outbox, a request that finds no server (refused, reset, timed out, 502/503) is retried
    with backoff for up to ``retry_for`` seconds; every request the bots make is safe to repeat (events are
    idempotent by sequence number, flow steps by the participant's state)."""

    def __init__(self, base_url: str, timeout: float = 30.0, retry_for: float = 0.0):
        self.base = base_url.rstrip("/")
        self.timeout, self.retry_for = timeout, retry_for
        self.retries = 0
        self.jar = http.cookiejar.CookieJar()
        self.opener = urllib.request.build_opener(urllib.request.HTTPCookieProcessor(self.jar))

    def _send(self, method, path, data=None, headers=None) -> Response:
        deadline, wait = time.monotonic() + self.retry_for, 0.1
        while True:
            req = urllib.request.Request(self.base + path, data=data, method=method, headers=headers or {})
            try:
                with self.opener.open(req, timeout=self.timeout) as r:
                    return Response(r.status, r.read())
            except urllib.error.HTTPError as e:
                response = Response(e.code, e.read())
                if e.code not in (502, 503) or time.monotonic() > deadline:
                    return response
            except (urllib.error.URLError, http.client.HTTPException, ConnectionError, TimeoutError) as e:
                if time.monotonic() > deadline:
                    raise FlowError(f"{method} {path}: no server ({e})") from None
            self.retries += 1
            time.sleep(wait)
            wait = min(wait * 2, 2.0)

    def get(self, path, headers=None) -> Response:
        return self._send("GET", path, headers=headers)

    def post(self, path, form=None, json_body=None, headers=None) -> Response:
        headers = dict(headers or {})
        if json_body is not None:
            headers["Content-Type"] = "application/json"
            return self._send("POST", path, json.dumps(json_body).encode(), headers)
        headers["Content-Type"] = "application/x-www-form-urlencoded"
        return self._send("POST", path, urlencode(form or {}).encode(), headers)

    def cookies(self) -> list[dict]:
        """The participant's cookies in the shape browsers take them (Playwright's ``add_cookies``), so that a
        browser can carry on where this transport stopped."""
        host = urlsplit(self.base).hostname
        return [{"name": c.name, "value": c.value or "", "domain": c.domain.lstrip(".") or host, "path": c.path,
                 "httpOnly": bool(c.has_nonstandard_attr("HttpOnly")), "secure": c.secure} for c in self.jar]


class LossyTransport:
    """A slow network that loses things: with probability ``loss`` a request never arrives, and with the same
    probability its response is lost after the server acted on it (a timeout); either way the bot sends it
    again, as a browser's retry or a participant's reload would. Every request must therefore be safe to repeat."""

    def __init__(self, inner, rng: np.random.Generator, loss: float, latency_s: float = 0.0):
        self.inner, self.rng, self.loss, self.latency_s = inner, rng, loss, latency_s
        self.lost = 0

    def _retry(self, send) -> Response:
        if self.latency_s:  # a slow network: each round trip waits (real time)
            time.sleep(float(self.rng.exponential(self.latency_s)))
        while self.rng.random() < self.loss:  # the request is lost on the way
            self.lost += 1
        response = send()
        while self.rng.random() < self.loss:  # the server acted, the answer is lost: send again
            self.lost += 1
            response = send()
        return response

    def get(self, path, headers=None) -> Response:
        return self._retry(lambda: self.inner.get(path, headers))

    def post(self, path, form=None, json_body=None, headers=None) -> Response:
        return self._retry(lambda: self.inner.post(path, form=form, json_body=json_body, headers=headers))

    @property
    def retries(self) -> int:
        return getattr(self.inner, "retries", 0) + self.lost
