"""Faults: the server killed with SIGKILL while simulated participants work (the short form of
benchmarks/bench_kill.py, real gunicorn processes on loopback)."""

from __future__ import annotations

import json
import subprocess
import sys

import pytest
from support import ROOT


@pytest.mark.slow
def test_participants_survive_repeated_kill_9_of_the_server(demo_resources):
    proc = subprocess.run([sys.executable, str(ROOT / "benchmarks" / "bench_kill.py"), "--participants", "6",
                           "--kills", "5", "--seed", "1"], capture_output=True, text=True, timeout=600, cwd=ROOT)
    out = json.loads(proc.stdout)
    assert out["kills"] >= 5 and out["retries"] > 0, out  # the bots did meet a dead server
    assert out["completed"] == out["completed_in_db"] == out["participants_in_db"] == 6, out
    assert out["events_stored"] == out["events_generated"] and out["duplicates"] == 0, out
    assert out["rows_balanced"] and out["integrity"] == "ok", out
    assert proc.returncode == 0, proc.stderr
