"""An external suggestion engine for the HTTP engine's tests: its own process, the standard library only (so, in
effect, any language), and one behaviour per path — a good one and several hostile ones.

    python tests/external_engine.py PORT_FILE

binds a free loopback port, writes it to PORT_FILE and serves until killed. Paths (POST):

/good        a valid answer: the query's categories in reverse alphabetical order, each placed upright at the
             click, turned 90° (kept alive)
/slow        the good answer after 2 s
/garbage     200 with a body that is not JSON
/nan         a score of NaN (Python's NaN token, which JSON does not have)
/unknown     a category the query did not allow
/scaled      a placement scaled by 2 (not rigid)
/many        more suggestions than any study allows (5,000)
/huge        a 100 MB body (Content-Length says so), streamed until the client goes
/hang        headers and 10 of the 1,000 bytes promised, then nothing until the client goes
/drip        the status line one byte every 50 ms
/error       500 with a short message
/stream      200 with no length, the connection to close at the end, and bytes until the client goes
/upside      a placement standing on the object's back, said to stand on its bottom
/idle-close  the good answer, then the connection closed 0.2 s later (as servers close idle connections)
/flaky?k=K   for each K: 500 on the first query, the good answer on the next, and so on
/count       200 {"connections": n}: connections accepted so far (for keep-alive checks; GET or POST)
/close       the good answer with Connection: close, then the connection closed
/http10      the good answer as Python's http.server writes it: HTTP/1.0, no Content-Length, the end of the
             answer the connection's close
"""

from __future__ import annotations

import json
import socket
import sys
import threading
import time
from pathlib import Path

CONNECTIONS = 0
LOCK = threading.Lock()
FLAKY: dict[str, int] = {}


def good_answer(query: dict, top: int | None = None) -> dict:
    categories = sorted(query["categories"], reverse=True)[: top or query["top"]]
    x, y, z = query["point"]
    turned = [0.0, 0.0, -1.0, 0.0, 0.0, 1.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, x, y, z, 1.0]  # 90° about +Y
    return {"suggestions": [{"category": c, "score": float(len(categories) - i), "placement": turned,
                             "terms": {"external": 1.0}} for i, c in enumerate(categories)]}


def read_request(f) -> tuple[str, str, bytes] | None:
    line = f.readline()
    if not line:
        return None
    method, path, _ = line.decode("latin-1").split(" ", 2)
    length = 0
    while True:
        header = f.readline()
        if header in (b"\r\n", b"\n", b""):
            break
        name, _, value = header.decode("latin-1").partition(":")
        if name.strip().lower() == "content-length":
            length = int(value.strip())
    return method, path, f.read(length) if length else b""


def send(conn: socket.socket, status: str, body: bytes, extra: str = "") -> None:
    conn.sendall(f"HTTP/1.1 {status}\r\nContent-Type: application/json\r\nContent-Length: {len(body)}\r\n{extra}"
                 "\r\n".encode() + body)


def serve(conn: socket.socket) -> None:
    global CONNECTIONS
    with LOCK:
        CONNECTIONS += 1
    f = conn.makefile("rb")
    try:
        while True:
            request = read_request(f)
            if request is None:
                return
            _, target, body = request
            path, _, key = target.partition("?")
            if path == "/count":
                send(conn, "200 OK", json.dumps({"connections": CONNECTIONS}).encode())
                continue
            query = json.loads(body)
            if path in ("/good", "/slow"):
                if path == "/slow":
                    time.sleep(2.0)
                send(conn, "200 OK", json.dumps(good_answer(query)).encode())
            elif path == "/garbage":
                send(conn, "200 OK", b"{not json at all")
            elif path in ("/nan", "/unknown", "/scaled"):
                answer = good_answer(query)
                item = answer["suggestions"][0]
                if path == "/nan":
                    item["score"] = float("nan")
                elif path == "/unknown":
                    item["category"] = "NoSuchCategory"
                else:
                    item["placement"] = [2 * v if i < 12 else v for i, v in enumerate(item["placement"])]
                send(conn, "200 OK", json.dumps(answer).encode())  # json writes NaN as the token NaN
            elif path == "/many":
                answer = good_answer(query)
                answer["suggestions"] = answer["suggestions"][:1] * 5000
                send(conn, "200 OK", json.dumps(answer).encode())
            elif path == "/huge":
                size = 100 * 1024 * 1024
                conn.sendall(f"HTTP/1.1 200 OK\r\nContent-Type: application/json\r\nContent-Length: {size}\r\n\r\n"
                             .encode())
                chunk = b"[" * 65536
                for _ in range(size // len(chunk)):
                    conn.sendall(chunk)
                return
            elif path == "/hang":
                conn.sendall(b"HTTP/1.1 200 OK\r\nContent-Type: application/json\r\nContent-Length: 1000\r\n\r\n"
                             b'{"suggest')
                while conn.recv(1):  # until the client closes
                    pass
                return
            elif path == "/drip":
                for byte in b"HTTP/1.1 200 OK\r\n":
                    conn.sendall(bytes([byte]))
                    time.sleep(0.05)
                return
            elif path == "/error":
                send(conn, "500 Internal Server Error", b'{"error": "boom"}')
            elif path == "/stream":
                conn.sendall(b"HTTP/1.1 200 OK\r\nContent-Type: application/json\r\nConnection: close\r\n\r\n")
                while True:
                    conn.sendall(b" " * 65536)
            elif path == "/upside":
                answer = good_answer(query)
                x, y, z = query["point"]
                answer["suggestions"][0].update(attachment_face="bottom", placement=[
                    1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, -1.0, 0.0, 0.0, x, y, z, 1.0])  # front up
                send(conn, "200 OK", json.dumps(answer).encode())
            elif path == "/close":
                send(conn, "200 OK", json.dumps(good_answer(query)).encode(), "Connection: close\r\n")
                return
            elif path == "/http10":
                conn.sendall(b"HTTP/1.0 200 OK\r\nServer: BaseHTTP/0.6 Python/3.11\r\nContent-Type: application/json"
                             b"\r\n\r\n" + json.dumps(good_answer(query)).encode())
                return
            elif path == "/idle-close":
                send(conn, "200 OK", json.dumps(good_answer(query)).encode())
                time.sleep(0.2)
                return
            elif path == "/flaky":
                with LOCK:
                    FLAKY[key] = FLAKY.get(key, 0) + 1
                    n = FLAKY[key]
                if n % 2:
                    send(conn, "500 Internal Server Error", b'{"error": "flaky"}')
                else:
                    send(conn, "200 OK", json.dumps(good_answer(query)).encode())
            else:
                send(conn, "404 Not Found", b"{}")
    except (OSError, ValueError):
        return
    finally:
        conn.close()


def main() -> int:
    server = socket.socket()
    server.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
    server.bind(("127.0.0.1", 0))
    server.listen(64)
    Path(sys.argv[1]).write_text(str(server.getsockname()[1]))
    while True:
        conn, _ = server.accept()
        threading.Thread(target=serve, args=(conn,), daemon=True).start()


if __name__ == "__main__":
    sys.exit(main())
