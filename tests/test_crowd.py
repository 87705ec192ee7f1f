"""The realistic crowd of the ingestion benchmark (benchmarks/crowd.py, realistic.py): the outbox's batches, the
shape of what a participant sends, and a small crowd taking the whole study over real HTTP with the server killed
midway (the short form of ``bench_ingest.py --realistic --kill``)."""

from __future__ import annotations

import json
import subprocess
import sys

import crowd
import pytest
import realistic
from support import ROOT


def test_the_outbox_sends_what_was_logged_one_second_after_the_first_unsent_event():
    times = [0, 200, 999, 1000, 1001, 5000, 5100, 9000]
    assert crowd.outbox_batches(times) == [[0, 1, 2, 3], [4], [5, 6], [7]]
    assert crowd.outbox_batches(list(range(0, 500, 100)), most=2) == [[0, 1], [2, 3], [4]]
    assert crowd.outbox_batches([]) == []


def test_the_shape_counts_per_minute_of_trial_time():
    trial = crowd.TrialTrace("basic", "desk", events=[{"t": 0.0}, {"t": 500.0}, {"t": 30_000.0}, {"t": 60_000.0}],
                             suggests=[({}, "a")], searches=[("/search?q=mug", "b"), ("/search?q=cup", "c")])
    shape = crowd.shape([[trial]])
    assert shape["events_per_min"] == {"median": 4.0, "p95": 4.0}
    assert shape["batches_per_min"]["median"] == 3.0  # [0, 500], [30 000], [60 000]
    assert shape["suggestions_per_min"]["median"] == 1.0 and shape["searches_per_min"]["median"] == 2.0
    assert shape["batch_size"] == {"median": 1, "p95": 2, "max": 2}


def test_capacity_keeps_the_headroom():
    assert realistic.capacity(30.0) == 1000  # 30 ms a participant-minute: half of a core's 60 000 ms
    assert realistic.capacity(30.0, headroom=1.0) == 2000


def test_the_crowds_study_keeps_the_practice_and_one_scene_and_lets_the_crowd_in(tmp_path):
    from study_server.studies.study_file import load_study

    study = load_study(crowd.bench_study(tmp_path / "short", arrivals=5000))
    assert study.arrivals_per_address_per_hour == 5000
    assert sorted(study.scenes) == ["desk-corner", "practice"]
    assert [list(p) for p in study.periods] == [["desk-corner"]]
    assert len(study.conditions) == 3 and study.practice == ("practice", "full") and study.consent_text
    whole = load_study(crowd.bench_study(tmp_path / "whole", scenes=None))
    assert len(whole.scenes) == 4 and len(whole.periods[0]) == 3


@pytest.mark.slow
def test_a_crowd_takes_the_whole_study_and_loses_nothing_when_the_server_is_killed(demo_resources):
    proc = subprocess.run([sys.executable, str(ROOT / "benchmarks" / "bench_ingest.py"), "--realistic",
                           "--participants", "6", "--pace", "40", "--arrival", "1", "--record", "3", "--kill"],
                          capture_output=True, text=True, timeout=600, cwd=ROOT)
    out = json.loads(proc.stdout)
    (run,) = out["runs"]
    assert [f[0] for f in run["faults"]] == ["killed", "restarted"], run
    assert run["retries"].get("no server", 0) > 0, run  # the participants did meet a dead server
    assert run["codes_given"] == run["completed_in_db"] == run["participants_in_db"] == 6, run
    assert run["events_acknowledged"] == run["events_stored"] > 0 and run["lost"] == 0, run
    assert run["rows_balanced"] and not run["failures"], run
    assert {"events", "suggest", "search", "page", "done"} <= set(run["latency"]), run
    assert run["load_generator_lag_ms"]["max"] >= run["load_generator_lag_ms"]["p95"] >= 0, run
    assert out["shape"]["events_per_min"]["median"] > 0
    assert proc.returncode == 0, proc.stderr


def test_the_capacity_table_is_made_from_the_runs():
    runs = [{"database": "postgresql", "app_cpu_ms_per_participant_minute": 50.0, "participants_per_app_core": 600,
             "database_cpu_s": 12.0, "participant_minutes": 1000.0,
             "latency": {"events": {"p95_ms": 20.0}, "suggest": {"p95_ms": 30.0}}},
            {"database": "sqlite-wal", "app_cpu_ms_per_participant_minute": 40.0, "participants_per_app_core": 750,
             "database_cpu_s": "in the app servers", "participant_minutes": 1000.0, "latency": {}}]
    rows = realistic.capacity_table(runs)
    assert [r["database_cpu_ms_per_participant_minute"] for r in rows] == ["12.0 ms", "in the app servers"]
    text = realistic.table_text(rows).splitlines()
    assert len(text) == 4 and "| postgresql | 50.0 ms | 600 | 12.0 ms | 20.0 ms | 30.0 ms |" in text


def test_nginx_timings_are_read_from_where_the_run_began_and_split_at_arrival(tmp_path):
    from serverproc import read_timings

    log = tmp_path / "access.log"
    log.write_text("100.000 POST /api/events 200 0.003\n")
    start = log.stat().st_size
    with log.open("a") as f:  # (nginx writes a line when a request ends: the first began at 200.25)
        f.write("200.500 POST /api/events 200 0.250\n200.600 GET /study/x/ 200 0.040\n"
                "300.100 POST /api/events 200 0.200\n301.000 POST /api/events 200 0.010\n"
                "301.100 POST /api/suggest 200 0.020\n301.150 POST /api/suggest 502 0.001\n"
                "301.200 GET /favicon.ico 404 0.001\n301.300 GET /api/scenes/a b 200 0.004\nnot a timing line\n")
    timings = read_timings(log, start)
    assert timings[0] == (200.25, "POST", "/api/events", 200, 250.0) and len(timings) == 8
    assert timings[-1][2] == "/api/scenes/a b"  # a decoded path with a space
    figures = realistic.server_side(timings, settled_epoch=300.0)
    whole, settled = figures["server_latency"], figures["server_latency_once_arrived"]
    assert whole["events"]["n"] == 3 and whole["events"]["max_ms"] == 250.0
    assert whole["page"]["n"] == 1 and "favicon" not in str(whole)
    # begun before everyone had arrived (299.9), ended after: not "once arrived"
    assert settled["events"] == {"n": 1, "p50_ms": 10.0, "p95_ms": 10.0, "max_ms": 10.0}
    assert settled["suggest"]["n"] == 1 and "page" not in settled and settled["scene"]["n"] == 1
    assert figures["server_errors"] == {"suggest": 1}  # nginx's 502: counted, not timed


def test_an_empty_schedule_row_counts_against_the_balance():
    from demostudy import rows_balance
    from serverproc import DEMO_STUDY

    from study_server.studies.study_file import load_study

    study = load_study(DEMO_STUDY)
    rows, balanced = rows_balance([0, 1, 2, 3, 4, 5] * 2, study)
    assert balanced and rows == {r: 2 for r in range(6)}
    rows, balanced = rows_balance([0, 1, 2, 3, 4] * 2, study)
    assert not balanced and rows[5] == 0
    assert not rows_balance([], study)[1]
