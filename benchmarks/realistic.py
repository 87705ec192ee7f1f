"""The realistic crowd as a benchmark (``bench_ingest.py --realistic``): what one participant sends, measured from
simulated participants (:mod:`crowd`), then ``--participants`` of them taking the whole study at once over real
HTTP — through nginx over TLS to app servers on PostgreSQL (``--database postgresql --via-proxy``), or to
`make serve`'s server on SQLite — checked in the database afterwards: every event stored once, every participant
completed with a code, the schedule's rows balanced. ``--kill`` kills one app server (SIGKILL, its whole process
group) a third of the way in and starts it again three seconds later. ``--capacity`` prints, from the app servers'
CPU per minute of a participant's time, how many participants one app-server core carries (:func:`capacity`).
"""

from __future__ import annotations

import asyncio
import signal
import tempfile
import time
from collections import Counter
from pathlib import Path

import crowd
import tests_path  # noqa: F401 (tests/ on the path, for the shared test infrastructure)
from demostudy import rows_balance
from serverproc import own_cpu_seconds
from stacks import postgres_stack, sqlite_stack

from study_server.studies.study_file import load_study

#: The headroom rule: plan for the app servers' cores to be busy at most this share of the time on average, so a
#: wave of arrivals or a busy minute (up to twice the average) still finds a core to run on rather than a queue.
HEADROOM = 0.5


def capacity(cpu_ms_per_participant_minute: float, headroom: float = HEADROOM) -> int:
    """Participants at once that one app-server core carries: a core gives 60,000 ms of CPU a minute, of which
    ``headroom`` is planned for."""
    return int(headroom * 60_000 / cpu_ms_per_participant_minute)


def killer(stack, at_s: float, down_s: float, log: list):
    """A fault to run beside the crowd: at ``at_s`` SIGKILL the first app server's processes, ``down_s`` later
    start it again on the same port."""
    async def during():
        await asyncio.sleep(at_s)
        server = stack.servers[0]
        server.kill(signal.SIGKILL)
        log.append(("killed", round(at_s, 1)))
        await asyncio.sleep(down_s)
        loop = asyncio.get_running_loop()
        await loop.run_in_executor(None, lambda: server.start().wait_ready(60))
        log.append(("restarted", round(at_s + down_s, 1)))
    return during


def check_database(stack, tally: crowd.Tally, study) -> dict:
    """What the database holds against what the crowd was told: per participant, every event up to the seq the
    server acknowledged stored (else lost) and once (else duplicated); completed participants; the rows of
    ``study``'s schedule among them (:func:`demostudy.rows_balance`)."""
    stored_seqs: dict[str, set[int]] = {}
    for pid, seq in stack.query("SELECT p.platform_id, e.seq FROM events e JOIN participants p "
                                "ON p.id = e.participant_id"):
        stored_seqs.setdefault(pid, set()).add(seq)
    lost = sum(sum(1 for seq in range(acked + 1) if seq not in stored_seqs.get(pid, ()))
               for pid, acked in tally.acked.items())
    stored, distinct = stack.count()
    status = Counter(s for (s,) in stack.query("SELECT status FROM participants"))
    rows, balanced = rows_balance((r for (r,) in stack.query("SELECT row FROM participants "
                                                             "WHERE status = 'completed'")), study)
    return {"events_acknowledged": sum(a + 1 for a in tally.acked.values()), "events_stored": stored,
            "lost": lost, "duplicates": stored - distinct, "participants_in_db": sum(status.values()),
            "completed_in_db": status.get("completed", 0), "rows": rows, "rows_balanced": balanced}


def summary(latencies: dict[str, list[float]]) -> dict:
    """Per kind of request: how many, and their latency's median, 95th percentile and maximum (ms)."""
    return {kind: {"n": len(v), "p50_ms": round(crowd.percentile(v, 50), 1),
                   "p95_ms": round(crowd.percentile(v, 95), 1), "max_ms": round(max(v), 1)}
            for kind, v in sorted(latencies.items())}


#: The crowd's kinds of request by the path nginx logged (a crowd's "page" is a form's POST and the GET it is
#: sent on to, nginx's one request each).
SERVER_KINDS = (("/api/events", "events"), ("/api/suggest", "suggest"), ("/api/search", "search"),
                ("/api/trial/done", "done"), ("/api/scenes/", "scene"), ("/api/models", "models"), ("/study/", "page"))


def server_side(timings, settled_epoch: float) -> dict:
    """The latencies nginx measured (from a request's first byte to its answer's last, without the load
    generator's own delays), by kind, over the run and of the requests begun once every participant had arrived;
    answers of 500 and above (nginx's own while an app server is away) counted apart, not timed."""
    whole: dict[str, list[float]] = {}
    settled: dict[str, list[float]] = {}
    failed = Counter()
    for began, _method, path, status, ms in timings:
        kind = next((k for prefix, k in SERVER_KINDS if path.startswith(prefix)), None)
        if kind is None:
            continue
        if status >= 500:
            failed[kind] += 1
            continue
        whole.setdefault(kind, []).append(ms)
        if began >= settled_epoch:
            settled.setdefault(kind, []).append(ms)
    return {"server_latency": summary(whole), "server_latency_once_arrived": summary(settled),
            "server_errors": dict(failed)}


def run(stack, args, people, study, minutes: float) -> dict:
    """One crowd against ``stack``; its figures. ``minutes``: a participant's trials (the median recorded)."""
    log: list = []
    during = killer(stack, args.arrival + 60 * minutes / args.pace / 3, 3.0, log) if args.kill else None
    cpu, proxy_cpu, client_cpu = stack.cpu_seconds(), stack.proxy_cpu_seconds(), own_cpu_seconds()
    database_cpu = stack.database_cpu_seconds()
    log_from = stack.proxy.log_size() if stack.proxy else None
    started = time.perf_counter()
    tally = crowd.run_crowd(stack.base, study.id, args.participants, people, args.pace, args.arrival,
                            stack.cafile, args.seed, during)
    seconds = time.perf_counter() - started
    cpu, proxy_cpu = stack.cpu_seconds() - cpu, stack.proxy_cpu_seconds() - proxy_cpu
    client_cpu = own_cpu_seconds() - client_cpu
    if database_cpu is not None:
        database_cpu = stack.database_cpu_seconds() - database_cpu
    # a participant-minute is a minute of a person's trial time, as recorded (their pages before the first trial
    # add CPU but no minutes: the figure errs high)
    person_minutes = tally.person_minutes
    latency, settled = (summary(latencies) for latencies in (tally.latency, tally.settled))
    lag, lag_settled = ([ms for at, ms in tally.lag if at >= since] or [0.0]
                        for since in (float("-inf"), tally.settled_at))
    figures = {"database": stack.label, "participants": args.participants, "pace": args.pace,
               "arrival_s": args.arrival, "seconds": round(seconds, 1), "latency": latency,
               "latency_once_arrived": settled,
               "load_generator_lag_ms": {"p95": round(crowd.percentile(lag, 95), 1), "max": round(max(lag), 1),
                                         "p95_once_arrived": round(crowd.percentile(lag_settled, 95), 1)},
               "codes_given": sum(1 for c in tally.codes.values() if c), "failures": tally.failures[:10],
               "failed": len(tally.failures), "retries": dict(tally.retries), "faults": log,
               "app_cpu_s": round(cpu, 1), "proxy_cpu_s": round(proxy_cpu, 1),
               "database_cpu_s": round(database_cpu, 1) if database_cpu is not None else "in the app servers",
               "load_generator_cpu_s": round(client_cpu, 1),
               "participant_minutes": round(person_minutes, 1),
               "app_cpu_ms_per_participant_minute": round(1000 * cpu / person_minutes, 1) if person_minutes else None}
    if stack.proxy:
        figures |= server_side(stack.proxy.timings(log_from), tally.settled_epoch)
    figures |= check_database(stack, tally, study)
    if log:  # a killed server's processes took their CPU time with them: the figure would be too low
        figures["app_cpu_s"] = figures["app_cpu_ms_per_participant_minute"] = None
    elif figures["app_cpu_ms_per_participant_minute"]:
        figures["participants_per_app_core"] = capacity(figures["app_cpu_ms_per_participant_minute"])
    figures["ok"] = (not tally.failures and figures["codes_given"] == args.participants
                     and figures["completed_in_db"] == args.participants and figures["lost"] == 0
                     and figures["duplicates"] == 0 and figures["rows_balanced"]
                     and figures["events_stored"] == figures["events_acknowledged"])
    return figures


def main(args) -> dict:
    """``bench_ingest.py --realistic``: the shape, then the crowd on the stack asked for (and, with
    ``--capacity``, on SQLite too); the figures, with ``ok``."""
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        path = crowd.bench_study(tmp / "study", ("desk-corner",) if args.short_study else None,
                                 arrivals=10 * max(args.participants, args.record))
        people = crowd.record_trials(args.record, path, seed=args.seed)
        study = load_study(path)
        shape = crowd.shape(people)
        minutes = shape["trial_minutes_per_participant"]["median"]
        out = {"benchmark": "ingest-realistic", "study": "demo, practice + desk-corner" if args.short_study else
               "demo", "shape": shape}
        runs = []
        if args.database == "postgresql":
            with postgres_stack(tmp / "pg", args.workers, args.via_proxy, path, args.apps) as stack:
                runs.append(run(stack, args, people, study, minutes))
        if args.database == "sqlite" or args.capacity:
            with sqlite_stack(tmp / "sqlite", args.workers, path) as stack:
                runs.append(run(stack, args, people, study, minutes))
    out["runs"] = runs
    if args.capacity:
        out["capacity"] = capacity_table(runs)
    out["ok"] = all(r.pop("ok") for r in runs)
    return out


def table_text(rows: list[dict]) -> str:
    """The capacity table as the README prints it (Markdown)."""
    lines = ["| database | app servers' CPU per participant-minute | participants at once per app-server core "
             f"(cores busy ≤ {HEADROOM:.0%}) | database's CPU per participant-minute | events p95 | "
             "suggestions p95 |", "|---|---|---|---|---|---|"]
    lines += [f"| {r['database']} | {r['app_cpu_ms_per_participant_minute']} ms | {r['participants_per_app_core']} | "
              f"{r['database_cpu_ms_per_participant_minute']} | {r['events_p95_ms']} ms | {r['suggest_p95_ms']} ms |"
              for r in rows]
    return "\n".join(lines)


def capacity_table(runs: list[dict]) -> list[dict]:
    """The README's table from measured runs: per database, the app servers' CPU per participant-minute, the
    participants at once one app-server core carries under the headroom rule, and the latencies seen."""
    return [{"database": r["database"], "app_cpu_ms_per_participant_minute": r["app_cpu_ms_per_participant_minute"],
             "participants_per_app_core": r.get("participants_per_app_core"), "headroom": HEADROOM,
             "database_cpu_ms_per_participant_minute": (
                 f"{round(1000 * r['database_cpu_s'] / r['participant_minutes'], 1)} ms"
                 if isinstance(r["database_cpu_s"], float) else r["database_cpu_s"]),
             "events_p95_ms": r["latency"].get("events", {}).get("p95_ms"),
             "suggest_p95_ms": r["latency"].get("suggest", {}).get("p95_ms")} for r in runs]
