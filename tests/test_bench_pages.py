"""The participant-path benchmark runs and prints its JSON: every participant reaches the end page (its walk asserts
that), through the pages a person requests."""

from __future__ import annotations

import json
import subprocess
import sys

from support import ROOT


def test_the_page_benchmark_walks_participants_to_their_codes(demo_resources):
    ran = subprocess.run([sys.executable, str(ROOT / "benchmarks" / "bench_pages.py"), "--participants", "2",
                          "--runs", "1"], capture_output=True, text=True, timeout=300, cwd=ROOT)
    assert ran.returncode == 0, ran.stderr[-2000:]
    out = json.loads(ran.stdout)
    walk = out["walk"]
    assert out["benchmark"] == "pages" and walk["cpu_ms_per_participant_median"] > 0
    # entry, device, consent, demographics, 3 instruction pages, 10 trials (page, events, done) with a briefing
    # before 3 or 4 of them, the exit survey: about 40 requests
    assert 38 <= walk["requests_per_participant"] <= 46
