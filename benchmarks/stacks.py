"""What a load test runs against: the study server as `make serve` runs it (gunicorn on SQLite in WAL mode), or as
the README deploys it (N app servers on PostgreSQL, behind nginx over TLS when asked) — each a :class:`Stack`."""

from __future__ import annotations

import os
import signal
import sqlite3
from collections.abc import Callable
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path

import tests_path  # noqa: F401 (tests/ on the path, for the shared test infrastructure)
from serverproc import DEMO_STUDY, NginxProxy, StudyServer


@dataclass
class Stack:
    """What the load goes to: the base URL, the app servers' CPU seconds so far, ``query(sql)``: the rows of a
    query on its database, its app servers (to kill one) and the proxy in front, if any."""

    base: str
    label: str
    cpu_seconds: Callable[[], float]
    query: Callable[[str], list[tuple]]
    #: the database server's CPU seconds so far (None: SQLite, whose work is the app servers')
    database_cpu_seconds: Callable[[], float | None] = lambda: None
    servers: list[StudyServer] = field(default_factory=list)
    #: nginx in front, when there is one (its access log times every request on the server's side)
    proxy: NginxProxy | None = None

    def proxy_cpu_seconds(self) -> float:
        """The proxy's CPU seconds so far (0 without one)."""
        return self.proxy.cpu_seconds() if self.proxy else 0.0

    @property
    def cafile(self) -> str | None:
        """The certificate a client trusts to reach the proxy over TLS (None: plain HTTP)."""
        return str(self.proxy.cert) if self.proxy else None

    def count(self) -> tuple[int, int]:
        """(stored, distinct by participant and seq) event rows."""
        return tuple(self.query(COUNT)[0])


COUNT = "SELECT count(*), (SELECT count(*) FROM (SELECT DISTINCT participant_id, seq FROM events) d) FROM events"


@contextmanager
def sqlite_stack(tmp: Path, workers: int, study: Path = DEMO_STUDY):
    """`make serve`'s server: gunicorn with ``workers`` workers on SQLite in WAL mode."""
    database = tmp / "bench.sqlite3"
    with StudyServer(tmp / "instance", f"sqlite:///{database}", workers, study=study) as server:
        def query(sql: str) -> list[tuple]:
            with sqlite3.connect(database) as conn:
                return conn.execute(sql).fetchall()
        yield Stack(server.base, "sqlite-wal", server.cpu_seconds, query, servers=[server])


@contextmanager
def postgres_stack(tmp: Path, workers: int, via_proxy: bool, study: Path = DEMO_STUDY, apps: int | None = None):
    """App servers (``apps``; default one, or two behind the proxy) of ``workers`` gunicorn workers each on a
    throwaway PostgreSQL, behind nginx over TLS when ``via_proxy`` (the deployment the README gives:
    ``study deploy-files``)."""
    from serverproc import ThrowawayPostgres
    from sqlalchemy import create_engine, text

    apps = apps or (2 if via_proxy else 1)
    with ThrowawayPostgres() as pg:
        url = pg.create("bench")
        env = {"SCENESUGGEST_PROXY_HOPS": "1"} if via_proxy else {}
        servers = [StudyServer(tmp / f"instance-{i}", url, workers, migrate=i == 0, env=env, study=study)
                   for i in range(apps)]
        proxy = NginxProxy(tmp / "nginx", [a.port for a in servers]) if via_proxy else None
        engine = create_engine(url)
        try:
            for a in servers:
                a.start().wait_ready()
            if proxy:
                proxy.start()
                os.environ["SSL_CERT_FILE"] = os.environ["REQUESTS_CA_BUNDLE"] = str(proxy.cert)

            def query(sql: str) -> list[tuple]:
                with engine.connect() as con:
                    return [tuple(r) for r in con.execute(text(sql))]
            label = "postgresql" + (f" behind nginx (TLS), {apps} app servers" if proxy else
                                    (f", {apps} app servers" if apps > 1 else ""))
            yield Stack(proxy.https if proxy else servers[0].base, label,
                        lambda: sum(a.cpu_seconds() for a in servers), query, pg.cpu_seconds, servers, proxy)
        finally:
            engine.dispose()
            if proxy:
                proxy.stop()
            for a in servers:
                if a.proc and a.proc.poll() is None:
                    a.kill(signal.SIGTERM)
