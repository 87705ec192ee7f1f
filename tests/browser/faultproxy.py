"""A reverse proxy on loopback between a browser and the study server that can answer for the server: the faults
of the field (a network gone, 422, 429, 503), the same in every browser engine, since no engine's driver is asked to
intercept anything. Requests pass to the server unchanged (with the browser's Host, so the pages' links and cookies
stay the proxy's) unless a rule answers them.

A rule is ``(path prefix, answer)``; ``answer(method, path, body)`` returns None to pass the request on,
``"drop"`` to close the connection without a word (what a browser sees when the network is gone), or a
``(status, headers, body)`` to send instead. ``hits`` counts what each rule answered.
"""

from __future__ import annotations

import threading
from collections import Counter
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer

import urllib3

HOP_BY_HOP = {"connection", "keep-alive", "proxy-authenticate", "proxy-authorization", "te", "trailers",
              "transfer-encoding", "upgrade", "content-length"}


class FaultProxy:
    def __init__(self, upstream: str):
        self.upstream = upstream.rstrip("/")
        self.rules: list[tuple[str, object]] = []
        self.hits: Counter = Counter()
        self._pool = urllib3.PoolManager(maxsize=16, retries=False)
        proxy = self

        class Handler(BaseHTTPRequestHandler):
            protocol_version = "HTTP/1.1"

            def log_message(self, *args):  # quiet
                pass

            def _any(self):
                length = int(self.headers.get("Content-Length") or 0)
                body = self.rfile.read(length) if length else b""
                answer = proxy._answer(self.command, self.path, body)
                if answer == "drop":
                    self.close_connection = True
                    self.connection.shutdown(2)
                    return
                if answer is None:
                    headers = {k: v for k, v in self.headers.items() if k.lower() not in HOP_BY_HOP}
                    r = proxy._pool.request(self.command, proxy.upstream + self.path, body=body or None,
                                            headers=headers, redirect=False, preload_content=True)
                    answer = (r.status, [(k, v) for k, v in r.headers.items() if k.lower() not in HOP_BY_HOP],
                              r.data)
                status, headers, data = answer
                self.send_response(status)
                for k, v in (headers.items() if isinstance(headers, dict) else headers):
                    self.send_header(k, v)
                self.send_header("Content-Length", str(len(data)))
                self.end_headers()
                if self.command != "HEAD":
                    self.wfile.write(data)

            do_GET = do_POST = do_PUT = do_DELETE = do_HEAD = _any

        self._server = ThreadingHTTPServer(("127.0.0.1", 0), Handler)
        self._server.daemon_threads = True
        self.base = f"http://127.0.0.1:{self._server.server_address[1]}"
        self._thread = threading.Thread(target=self._server.serve_forever, daemon=True)

    def _answer(self, method: str, path: str, body: bytes):
        for prefix, rule in list(self.rules):
            if path.startswith(prefix):
                answer = rule(method, path, body)
                if answer is not None:
                    self.hits[prefix] += 1
                    return answer
        return None

    def __enter__(self):
        self._thread.start()
        return self

    def __exit__(self, *exc):
        self._server.shutdown()
        self._server.server_close()
