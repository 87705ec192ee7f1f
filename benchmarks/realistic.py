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
import resource
import signal
import tempfile
import time
from collections import Counter
from pathlib import Path

import crowd
from stacks import postgres_stack, sqlite_stack

#: The headroom rule: plan for the app servers' cores to be busy at most this share of the time on average, so a
#: wave of arrivals or a slow minute (twice the average) still finds them free.
HEADROOM = 0.5


def capacity(cpu_ms_per_participant_minute: float, headroom: float = HEADROOM) -> int:
    """Participants at once that one app-server core carries: a core gives 60,000 ms of CPU a minute, of which
    ``headroom`` is planned for."""
    return int(headroom * 60_000 / cpu_ms_per_participant_minute)


def client_cpu_seconds() -> float:
    """This process's CPU time (user + system, seconds): the load generator's own."""
    usage = resource.getrusage(resource.RUSAGE_SELF)
    return usage.ru_utime + usage.ru_stime


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


def check_database(stack, tally: crowd.Tally) -> dict:
    """What the database holds against what the crowd sent: events per participant (lost, duplicated), completed
    participants and their codes, rows of the schedule among them."""
    per_participant = dict(stack.query(
        "SELECT p.platform_id, count(e.id) FROM participants p LEFT JOIN events e ON e.participant_id = p.id "
        "GROUP BY p.platform_id"))
    stored, distinct = stack.count()
    status = Counter(s for (s,) in stack.query("SELECT status FROM participants"))
    rows = Counter(r for (r,) in stack.query("SELECT row FROM participants WHERE status = 'completed'"))
    lost = sum(max(0, n - per_participant.get(pid, 0)) for pid, n in tally.events_sent.items())
    return {"events_sent": sum(tally.events_sent.values()), "events_stored": stored, "lost": lost,
            "duplicates": stored - distinct, "participants_in_db": sum(status.values()),
            "completed_in_db": status.get("completed", 0), "rows": dict(sorted(rows.items())),
            "rows_balanced": bool(rows) and max(rows.values()) - min(rows.values()) <= 1}


def run(stack, args, people, study_id: str) -> dict:
    """One crowd against ``stack``; its figures."""
    shape = crowd.shape(people)
    minutes = shape["trial_minutes_per_participant"]["median"]
    log: list = []
    during = killer(stack, args.arrival + 60 * minutes / args.pace / 3, 3.0, log) if args.kill else None
    cpu, proxy_cpu, client_cpu = stack.cpu_seconds(), stack.proxy_cpu_seconds(), client_cpu_seconds()
    started = time.perf_counter()
    tally = crowd.run_crowd(stack.base, study_id, args.participants, people, args.pace, args.arrival,
                            stack.cafile, args.seed, during)
    seconds = time.perf_counter() - started
    cpu, proxy_cpu = stack.cpu_seconds() - cpu, stack.proxy_cpu_seconds() - proxy_cpu
    client_cpu = client_cpu_seconds() - client_cpu
    person_minutes = sum(tally.seconds.values()) * args.pace / 60.0
    latency, settled = (
        {kind: {"n": len(v), "p50_ms": round(crowd.percentile(v, 50), 1), "p95_ms": round(crowd.percentile(v, 95), 1),
                "max_ms": round(max(v), 1)} for kind, v in sorted(latencies.items())}
        for latencies in (tally.latency, tally.settled))
    figures = {"database": stack.label, "participants": args.participants, "pace": args.pace,
               "arrival_s": args.arrival, "seconds": round(seconds, 1), "latency": latency,
               "latency_once_arrived": settled,
               "codes_given": sum(1 for c in tally.codes.values() if c), "failures": tally.failures[:10],
               "failed": len(tally.failures), "retries": tally.retries, "faults": log,
               "app_cpu_s": round(cpu, 1), "proxy_cpu_s": round(proxy_cpu, 1),
               "load_generator_cpu_s": round(client_cpu, 1),
               "participant_minutes": round(person_minutes, 1),
               "app_cpu_ms_per_participant_minute": round(1000 * cpu / person_minutes, 1) if person_minutes else None}
    figures |= check_database(stack, tally)
    if log:  # a killed server's processes took their CPU time with them: the figure would be too low
        figures["app_cpu_s"] = figures["app_cpu_ms_per_participant_minute"] = None
    elif figures["app_cpu_ms_per_participant_minute"]:
        figures["participants_per_app_core"] = capacity(figures["app_cpu_ms_per_participant_minute"])
    figures["ok"] = (not tally.failures and figures["codes_given"] == args.participants
                     and figures["completed_in_db"] == args.participants and figures["lost"] == 0
                     and figures["duplicates"] == 0 and figures["rows_balanced"]
                     and figures["events_stored"] == figures["events_sent"])
    return figures


def main(args) -> dict:
    """``bench_ingest.py --realistic``: the shape, then the crowd on the stack asked for (and, with
    ``--capacity``, on SQLite too); the figures, with ``ok``."""
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        study = crowd.bench_study(tmp / "study", ("desk-corner",) if args.short_study else None,
                                  arrivals=10 * args.participants)
        people = crowd.record_trials(args.record, study, seed=args.seed)
        study_id = crowd.study_id(study)
        out = {"benchmark": "ingest-realistic", "study": "demo, practice + desk-corner" if args.short_study else
               "demo", "shape": crowd.shape(people)}
        runs = []
        if args.database == "postgresql":
            with postgres_stack(tmp / "pg", args.workers, args.via_proxy, study, args.apps) as stack:
                runs.append(run(stack, args, people, study_id))
        if args.database == "sqlite" or args.capacity:
            with sqlite_stack(tmp / "sqlite", args.workers, study) as stack:
                runs.append(run(stack, args, people, study_id))
    out["runs"] = runs
    if args.capacity:
        out["capacity"] = capacity_table(runs)
    out["ok"] = all(r.pop("ok") for r in runs)
    return out


def table_text(rows: list[dict]) -> str:
    """The capacity table as the README prints it (Markdown)."""
    lines = ["| database | app CPU per participant-minute | participants at once per app-server core "
             f"(cores busy ≤ {HEADROOM:.0%}) | events p95 | suggestions p95 |", "|---|---|---|---|---|"]
    lines += [f"| {r['database']} | {r['app_cpu_ms_per_participant_minute']} ms | {r['participants_per_app_core']} | "
              f"{r['events_p95_ms']} ms | {r['suggest_p95_ms']} ms |" for r in rows]
    return "\n".join(lines)


def capacity_table(runs: list[dict]) -> list[dict]:
    """The README's table from measured runs: per database, the app servers' CPU per participant-minute, the
    participants at once one app-server core carries under the headroom rule, and the latencies seen."""
    return [{"database": r["database"], "app_cpu_ms_per_participant_minute": r["app_cpu_ms_per_participant_minute"],
             "participants_per_app_core": r.get("participants_per_app_core"), "headroom": HEADROOM,
             "events_p95_ms": r["latency"].get("events", {}).get("p95_ms"),
             "suggest_p95_ms": r["latency"].get("suggest", {}).get("p95_ms")} for r in runs]
