"""The study server as `make serve` runs it — gunicorn serving the demo study — as a subprocess on a free
loopback port: for the benchmarks and for the tests that need real HTTP and real processes."""

from __future__ import annotations

import os
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
    from study_server.prepare import problems
    from study_server.study_file import load_study

    found = problems(load_study(DEMO_STUDY))
    return "; ".join(found.values()) + " (run `make demo`)" if found else None


def free_port() -> int:
    s = socket.socket()
    s.bind(("127.0.0.1", 0))
    port = s.getsockname()[1]
    s.close()
    return port


class StudyServer:
    """gunicorn on a fixed free port over one database; can be killed and started again on the same port.
    ``migrate`` brings the schema up to date first (skip it when the caller already did)."""

    def __init__(self, instance: Path, database_url: str, workers: int = 2, migrate: bool = True,
                 study: Path = DEMO_STUDY):
        self.env = {**os.environ, "SCENESUGGEST_INSTANCE": str(instance), "DATABASE_URL": database_url,
                    "SCENESUGGEST_STUDIES": str(study), "SCENESUGGEST_SECRET_KEY": "loopback-only-" + "x" * 32}
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
        total, tick = 0.0, os.sysconf("SC_CLK_TCK")
        for stat in Path("/proc").glob("[0-9]*/stat"):
            try:
                fields = stat.read_text().rsplit(")", 1)[1].split()
            except OSError:  # the process ended meanwhile
                continue
            if int(fields[2]) == self.proc.pid:  # fields from the state on: state, ppid, pgrp, …, utime, stime
                total += (int(fields[11]) + int(fields[12])) / tick
        return total

    def kill(self, sig: int = signal.SIGKILL) -> None:
        os.killpg(self.proc.pid, sig)
        self.proc.wait(timeout=30)

    def __enter__(self) -> StudyServer:
        self.start().wait_ready()
        return self

    def __exit__(self, *exc) -> None:
        self.kill(signal.SIGTERM)
