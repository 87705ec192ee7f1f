"""Puts tests/ on the import path: the test infrastructure the benchmarks share with the tests — the demo study's
app in process (demostudy), the server and PostgreSQL as processes (serverproc), the browsers (browsers). Imported
for that effect, before those modules."""

import sys
from pathlib import Path

TESTS = Path(__file__).resolve().parents[1] / "tests"
if str(TESTS) not in sys.path:
    sys.path.insert(0, str(TESTS))
