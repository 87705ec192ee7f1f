"""The study server as `make serve` runs it — gunicorn serving the demo study — as a subprocess on a free
loopback port: for the benchmarks and for the tests that need real HTTP and real processes."""

from __future__ import annotations

import os
import resource
import signal
import socket
import subprocess
import sys
import time
import urllib.request
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
DEMO_STUDY = ROOT / "study_server" / "demo" / "study.toml"


def demo_missing() -> str | None:
    """What the demo study lacks to be served (its priors and library; `make demo` builds them), or None."""
    from study_server.studies.prepare import problems
    from study_server.studies.study_file import load_study

    found = problems(load_study(DEMO_STUDY))
    return "; ".join(found.values()) + " (run `make demo`)" if found else None


def cpu_seconds_of(chosen) -> float:
    """CPU time (user + system, seconds) used so far by the live processes for which ``chosen(pid, ppid, pgrp)``
    is true."""
    total, tick = 0.0, os.sysconf("SC_CLK_TCK")
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            fields = stat.read_text().rsplit(")", 1)[1].split()
        except OSError:  # the process ended meanwhile
            continue
        # fields from the state on: state, ppid, pgrp, …, utime (11), stime (12)
        if chosen(int(stat.parent.name), int(fields[1]), int(fields[2])):
            total += (int(fields[11]) + int(fields[12])) / tick
    return total


def group_cpu_seconds(group: int) -> float:
    """CPU time (user + system, seconds) used so far by the live processes of process group ``group``."""
    return cpu_seconds_of(lambda pid, ppid, pgrp: pgrp == group)


def own_cpu_seconds() -> float:
    """This process's CPU time (user + system, seconds, all its threads): a load generator's own."""
    usage = resource.getrusage(resource.RUSAGE_SELF)
    return usage.ru_utime + usage.ru_stime


def free_port() -> int:
    s = socket.socket()
    s.bind(("127.0.0.1", 0))
    port = s.getsockname()[1]
    s.close()
    return port


def wait_for_port(port: int, timeout_s: float = 30.0) -> None:
    """Until something accepts connections on the loopback ``port``."""
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        try:
            socket.create_connection(("127.0.0.1", port), timeout=1).close()
            return
        except OSError:
            time.sleep(0.05)
    raise RuntimeError(f"nothing listens on port {port}")


class StudyServer:
    """gunicorn on a fixed free port over one database; can be killed and started again on the same port.
    ``migrate`` brings the schema up to date first (skip it when the caller already did)."""

    def __init__(self, instance: Path, database_url: str, workers: int = 2, migrate: bool = True,
                 study: Path = DEMO_STUDY, env: dict | None = None):
        self.env = {**os.environ, "SCENESUGGEST_INSTANCE": str(instance), "DATABASE_URL": database_url,
                    "SCENESUGGEST_STUDIES": str(study), "SCENESUGGEST_SECRET_KEY": "loopback-only-" + "x" * 32,
                    "SCENESUGGEST_WARM": "1",  # as 'study serve' runs it
                    **(env or {})}
        if migrate:
            subprocess.run([sys.executable, "-m", "scenesuggest.cli", "study", "migrate"], env=self.env, check=True,
                           capture_output=True)
        self.workers, self.port = workers, free_port()
        self.base = f"http://127.0.0.1:{self.port}"
        self.proc: subprocess.Popen | None = None

    def start(self) -> StudyServer:
        self.proc = subprocess.Popen([sys.executable, "-m", "gunicorn", "--workers", str(self.workers), "--bind",
                                      f"127.0.0.1:{self.port}", "study_server:create_app()"], env=self.env, cwd=ROOT,
                                     stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True)
        return self

    def wait_ready(self, timeout_s: float = 30.0) -> None:
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline:
            try:
                urllib.request.urlopen(f"{self.base}/api/openapi.json", timeout=5).close()
                return
            except OSError:
                time.sleep(0.1)
        raise RuntimeError("the study server did not start")

    def cpu_seconds(self) -> float:
        """CPU time (user + system, seconds) used so far by the server's processes (gunicorn and its workers, one
        process group)."""
        return group_cpu_seconds(self.proc.pid)

    def kill(self, sig: int = signal.SIGKILL) -> None:
        os.killpg(self.proc.pid, sig)
        self.proc.wait(timeout=30)

    def __enter__(self) -> StudyServer:
        self.start().wait_ready()
        return self

    def __exit__(self, *exc) -> None:
        self.kill(signal.SIGTERM)


NGINX_CONF = """daemon off;
user root;
worker_processes 1;
pid {prefix}/nginx.pid;
error_log {prefix}/error.log warn;
events {{ worker_connections 4096; }}
http {{
    include /etc/nginx/mime.types;
    default_type application/octet-stream;
    # when (epoch s), what, and how long nginx took from the request's first byte to the answer's last (s)
    log_format timing '$msec $request_method $uri $status $request_time';
    access_log {prefix}/access.log timing;
    client_body_temp_path {prefix}/tmp/body;
    proxy_temp_path {prefix}/tmp/proxy;
    fastcgi_temp_path {prefix}/tmp/fastcgi;
    uwsgi_temp_path {prefix}/tmp/uwsgi;
    scgi_temp_path {prefix}/tmp/scgi;
    include {prefix}/deploy/nginx/scenesuggest.conf;
}}
"""


def nginx_missing() -> str | None:
    import shutil

    if not shutil.which("nginx", path=os.environ.get("PATH", "") + ":/usr/sbin"):
        return "nginx is not installed (apt-get install nginx)"
    if not shutil.which("openssl"):
        return "openssl is not installed"
    return None


class NginxProxy:
    """nginx from Debian as a child process, all in ``prefix``, with the site configuration
    ``scenesuggest study deploy-files`` writes (the one shipped), a self-signed certificate for 127.0.0.1, and
    the given app servers' ports as its upstream. ``https`` is its base URL, ``cert`` the certificate to trust. Its
    access log (``prefix``/access.log) is in ``log_format``: ``timing`` (:func:`read_timings`) or the site's own."""

    def __init__(self, prefix: Path, app_ports: list[int], log_format: str = "timing"):
        from study_server.experimenter.deployment import Deployment, write_deploy_files

        self.prefix = prefix
        (prefix / "tmp").mkdir(parents=True)
        self.cert, key = prefix / "cert.pem", prefix / "key.pem"
        subprocess.run(["openssl", "req", "-x509", "-newkey", "rsa:2048", "-nodes", "-keyout", str(key), "-out",
                        str(self.cert), "-days", "1", "-subj", "/CN=127.0.0.1", "-addext",
                        "subjectAltName=IP:127.0.0.1"], check=True, capture_output=True)
        self.http_port, self.https_port = free_port(), free_port()
        write_deploy_files(prefix / "deploy", Deployment(
            "127.0.0.1", app_ports, self.http_port, self.https_port, address="127.0.0.1", cert=str(self.cert),
            key=str(key), nginx_dir=str(prefix / "deploy" / "nginx"), cache=str(prefix / "cache"),
            acme_root=str(prefix / "acme"), access_log=str(prefix / "access.log"), access_log_format=log_format,
            error_log=str(prefix / "error.log")))
        (prefix / "nginx.conf").write_text(NGINX_CONF.format(prefix=prefix))
        self.https = f"https://127.0.0.1:{self.https_port}"
        self.http = f"http://127.0.0.1:{self.http_port}"
        self.proc: subprocess.Popen | None = None

    def start(self) -> NginxProxy:
        import shutil

        nginx = shutil.which("nginx", path=os.environ.get("PATH", "") + ":/usr/sbin")
        self.proc = subprocess.Popen([nginx, "-c", str(self.prefix / "nginx.conf"), "-p", str(self.prefix)],
                                     stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, start_new_session=True)
        deadline = time.monotonic() + 10
        while time.monotonic() < deadline:
            try:
                socket.create_connection(("127.0.0.1", self.https_port), timeout=1).close()
                return self
            except OSError:
                if self.proc.poll() is not None:
                    raise RuntimeError("nginx did not start: " + self.proc.stderr.read().decode(errors="replace")
                                       ) from None
                time.sleep(0.05)
        raise RuntimeError("nginx did not start listening")

    def cpu_seconds(self) -> float:
        """CPU time used so far by nginx's master and worker."""
        return group_cpu_seconds(self.proc.pid)

    def log_size(self) -> int:
        """Bytes of the access log so far (where :meth:`timings` starts reading)."""
        log = self.prefix / "access.log"
        return log.stat().st_size if log.exists() else 0

    def timings(self, start: int = 0) -> list[tuple[float, str, str, int, float]]:
        """The requests nginx answered, from byte ``start`` of its access log on (:func:`read_timings`)."""
        return read_timings(self.prefix / "access.log", start)

    def stop(self) -> None:
        if self.proc and self.proc.poll() is None:
            os.killpg(self.proc.pid, signal.SIGQUIT)
            try:
                self.proc.wait(timeout=10)
            except subprocess.TimeoutExpired:
                os.killpg(self.proc.pid, signal.SIGKILL)
                self.proc.wait()

    def __enter__(self) -> NginxProxy:
        return self.start()

    def __exit__(self, *exc) -> None:
        self.stop()


def read_timings(log: Path, start: int = 0) -> list[tuple[float, str, str, int, float]]:
    """The requests of an access log in :data:`NGINX_CONF`'s ``timing`` format, from byte ``start`` on: (when it
    began, epoch s; method; path; status; how long nginx took, ms — the server's side of a latency, from the
    request's first byte to the answer's last, without the client's own delays). nginx logs a request when it ends
    (``$msec``); its beginning is that less its time. A line of another format is left out."""
    with open(log, "rb") as f:
        f.seek(start)
        lines = f.read().decode(errors="replace").splitlines()
    out = []
    for line in lines:
        try:  # the path is decoded ($uri): it may hold a space, the fields around it do not
            ended, method, rest = line.split(" ", 2)
            path, status, took = rest.rsplit(" ", 2)
            out.append((float(ended) - float(took), method, path, int(status), float(took) * 1000.0))
        except ValueError:
            continue
    return out


class ThrowawayPostgres:
    """A PostgreSQL server of Debian's on a free loopback port, its data in a temporary folder, run as the
    ``postgres`` user (TESTING.md); ``url`` is its ``postgres`` database, :meth:`create` makes another."""

    def __init__(self):
        import glob
        import shutil
        import tempfile

        bins = sorted(glob.glob("/usr/lib/postgresql/*/bin"))
        if not bins or not shutil.which("runuser"):
            raise RuntimeError("PostgreSQL is not installed (apt-get install postgresql)")
        self.bindir, self.run = bins[-1], ["runuser", "-u", "postgres", "--"]
        self.data = Path(tempfile.mkdtemp(prefix="scenesuggest-pg-"))  # pytest's tmp dirs are closed to others
        shutil.chown(self.data, "postgres")
        self.port = free_port()
        self.url = f"postgresql+psycopg://postgres@127.0.0.1:{self.port}/postgres"

    def start(self) -> ThrowawayPostgres:
        subprocess.run([*self.run, f"{self.bindir}/initdb", "-D", str(self.data / "db"), "-A", "trust", "-U",
                        "postgres"], check=True, capture_output=True)
        subprocess.run([*self.run, f"{self.bindir}/pg_ctl", "-D", str(self.data / "db"), "-l",
                        str(self.data / "log"), "-w", "-o", f"-c listen_addresses=127.0.0.1 -p {self.port} "
                        f"-k {self.data} -c fsync=off -c max_connections=200", "start"], check=True,
                       capture_output=True)
        for _ in range(50):
            if subprocess.run([*self.run, f"{self.bindir}/pg_isready", "-h", "127.0.0.1", "-p", str(self.port)],
                              capture_output=True).returncode == 0:
                break
            time.sleep(0.1)
        return self

    def cpu_seconds(self) -> float:
        """CPU time (user + system, seconds) used so far by the server: its postmaster and the processes it
        started (backends, writers), those alive now."""
        postmaster = int((self.data / "db" / "postmaster.pid").read_text().split()[0])
        return cpu_seconds_of(lambda pid, ppid, pgrp: postmaster in (pid, ppid))

    def create(self, name: str, owner: str | None = None) -> str:
        """A new empty database; returns its URL. With ``owner``, that login role (made if missing, not a
        superuser) owns it and the URL signs in as it, as an app's role does in production."""
        where = ["-h", "127.0.0.1", "-p", str(self.port), "-U", "postgres"]
        if owner:
            subprocess.run([*self.run, f"{self.bindir}/psql", *where, "-q", "-c",
                            f"DO $$ BEGIN IF NOT EXISTS (SELECT FROM pg_roles WHERE rolname = '{owner}') THEN "
                            f"CREATE ROLE {owner} LOGIN NOSUPERUSER; END IF; END $$"], check=True,
                           capture_output=True)
        subprocess.run([*self.run, f"{self.bindir}/createdb", *where, *(["-O", owner] if owner else []), name],
                       check=True, capture_output=True)
        base = self.url.rsplit("/", 1)[0] + "/" + name
        return base.replace("//postgres@", f"//{owner}@") if owner else base

    def stop(self) -> None:
        import shutil

        subprocess.run([*self.run, f"{self.bindir}/pg_ctl", "-D", str(self.data / "db"), "-m", "fast", "stop"],
                       capture_output=True)
        shutil.rmtree(self.data, ignore_errors=True)

    def __enter__(self) -> ThrowawayPostgres:
        return self.start()

    def __exit__(self, *exc) -> None:
        self.stop()
