"""Ingestion benchmark: concurrent participants posting batched events over real HTTP to the study server run as
`make serve` runs it (gunicorn, 2 workers, SQLite in WAL mode), with some batches sent twice on purpose.

The events are those a participant logs: the stream of one simulated participant taking the demo (recorded in
process first), renumbered — its scene changes carry their objects' states (event vocabulary 2; ``--vocabulary
1`` sends them as pages of the first version did, without states, to measure a server of that version).

Two phases: *paced* — every participant flushes a batch once a second, as the client's outbox does (with 50
participants and 100-event batches that offers 5,000 events/s) — and *saturated* — every participant posts
back to back, which measures the most the server can take (latency then is queueing).
During the paced phase every participant also asks for suggestions (one context query every ~5 s, as a person
placing objects would), so the latencies are those of ingestion and suggestion under each other's load.
Prints events/s stored, acknowledgement and suggestion latency percentiles, events sent vs rows stored, the server
processes' CPU time per 1,000 events stored (saturated: ingestion alone; paced: with the suggestions) and the
median size of an event as sent. Budget on a 2-core machine: ≥ 5,000 events/s with p95 ≤ 100 ms, nothing lost or
duplicated, ≤ 80 ms of server CPU per 1,000 events. The paced rate is events stored over the whole phase, whose
first second staggers the participants' starts, so it stays ~1–2% under the offered rate (printed beside it)
even when the server keeps up; ``--participants 55`` offers 5,500 events/s to show a paced rate above 5,000.
``--database postgresql`` runs the same load on a throwaway PostgreSQL server (``--via-proxy``: two app servers,
or ``--apps``, behind nginx over TLS, the deployment ``study deploy-files`` writes; nginx's CPU is reported apart),
then on SQLite in the same run, whose main figures are printed beside. The load generator runs on the same machine:
its own CPU is printed beside the server's.
``--realistic`` instead sends what people send: participants take the whole study at once (realistic.py;
``--kill`` kills an app server midway; ``--capacity`` prints how many participants an app-server core carries).
Usage: .venv/bin/python benchmarks/bench_ingest.py [--participants 50] [--batches 20] [--batch-size 100]
       [--database postgresql [--via-proxy] [--apps N]]
       .venv/bin/python benchmarks/bench_ingest.py --realistic --participants 1000 [--pace 1] [--arrival 120]
       [--kill | --capacity] [--database postgresql --via-proxy]
"""

from __future__ import annotations

import argparse
import json
import random
import sys
import tempfile
import threading
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import checkout
import tests_path  # noqa: F401 (tests/ on the path, for the shared test infrastructure)
from crowd import percentile
from demostudy import to_first_trial
from serverproc import demo_missing, nginx_missing, own_cpu_seconds
from stacks import Stack, postgres_stack, sqlite_stack

from scenesuggest.contract.events import SCENE_CHANGES
from simulation.transport import HttpTransport

ROOT = Path(__file__).resolve().parents[1]


def enrol(base: str, pid: str) -> str:
    """Walk one participant to the first trial over HTTP; returns its session token."""
    return to_first_trial(HttpTransport(base), pid).boot["token"]


def event_mix(vocabulary: int) -> list[dict]:
    """The events (type, trial, payload) one simulated participant logs taking the demo study, in order, as a page
    of ``vocabulary`` sends them: recorded in process on a throwaway database."""
    from crowd import record_trials

    mix = [{"type": e["type"], "trial": e["trial"], "payload": e["payload"]}
           for trial in record_trials(1)[0] for e in trial.events]
    if vocabulary == 1:
        mix = [{**e, "payload": {k: v for k, v in e["payload"].items() if k != "objects"}}
               if e["type"] in SCENE_CHANGES else e for e in mix]
    return mix


def participant(base: str, token: str, first_seq: int, batches: int, size: int, interval: float, resend: float,
                rng: random.Random, lat: list, errors: list, lock: threading.Lock, mix: list[dict],
                vocabulary: int) -> int:
    """Post ``batches`` batches of ``size`` events of ``mix`` (in turn, from a random place), one every
    ``interval`` seconds (0: back to back); returns the next seq."""
    import requests

    s = requests.Session()
    headers = {"Authorization": f"Bearer {token}", "Content-Type": "application/json"}
    seq = first_seq
    at = rng.randrange(len(mix))
    next_at = time.perf_counter() + rng.uniform(0, interval)
    for _ in range(batches):
        if interval:
            time.sleep(max(0.0, next_at - time.perf_counter()))
            next_at += interval
        now = time.time() * 1000
        events = [{"seq": seq + i, "t": now + i, **mix[(at + i) % len(mix)]} for i in range(size)]
        at += size
        seq += size
        body = {"page_id": "bench", "events": events} | ({"vocabulary": vocabulary} if vocabulary > 1 else {})
        data = json.dumps(body).encode()  # encoded before the clock starts: the latency is the server's answer
        sends = 2 if rng.random() < resend else 1
        for _ in range(sends):
            t = time.perf_counter()
            try:
                r = s.post(f"{base}/api/events", data=data, headers=headers, timeout=60)
                ok = r.status_code == 200 and r.json()["acked_seq"] == seq - 1
            except Exception as e:  # counted, not fatal
                ok = False
                r = e
            with lock:
                lat.append((time.perf_counter() - t) * 1000)
                if not ok:
                    errors.append(str(getattr(r, "status_code", r)))
    return seq


def suggester(base: str, token: str, every: float, rng: random.Random, stop: threading.Event, lat: list,
              errors: list, lock: threading.Lock) -> None:
    """Shift-clicks at the practice scene's objects, one context query every ``every`` seconds, until ``stop``."""
    import requests

    s = requests.Session()
    headers = {"Authorization": f"Bearer {token}"}
    state = s.get(f"{base}/api/session", headers=headers, timeout=30).json()
    trial = state["trial"]
    target = s.get(f"{base}/api/scenes/{trial['scene']}?which=target", headers=headers, timeout=30).json()
    objects = target["objects"]
    supported = [o for o in objects if o.get("parent")]
    while not stop.wait(rng.uniform(0.5, 1.5) * every):
        o = rng.choice(supported)
        body = json.dumps({"trial": trial["index"], "scene": {"objects": objects}, "parent": o["parent"],
                           "point": o["contact_point"], "normal": o["contact_normal"]}).encode()
        t = time.perf_counter()
        try:
            r = s.post(f"{base}/api/suggest", data=body, headers=headers | {"Content-Type": "application/json"},
                       timeout=60)
            ok = r.status_code == 200 and r.json()["suggestions"]
        except Exception as e:  # counted, not fatal
            ok, r = False, e
        with lock:
            lat.append((time.perf_counter() - t) * 1000)
            if not ok:
                errors.append(str(getattr(r, "status_code", r)))


def run_phase(server, tokens: list[str], seqs: list[int], args, interval: float, mix: list[dict],
              suggest_every: float = 0.0) -> dict:
    """One phase against ``server`` (a :class:`Stack`)."""
    base = server.base
    lat, errors, lock = [], [], threading.Lock()
    suggest_lat, suggest_errors, stop = [], [], threading.Event()
    started, cpu, proxy_cpu = time.perf_counter(), server.cpu_seconds(), server.proxy_cpu_seconds()
    client_cpu = own_cpu_seconds()
    with ThreadPoolExecutor(max_workers=2 * len(tokens)) as pool:
        helpers = [pool.submit(suggester, base, tokens[k], suggest_every, random.Random(1000 + k), stop,
                               suggest_lat, suggest_errors, lock) for k in range(len(tokens)) if suggest_every]
        futures = [pool.submit(participant, base, tokens[k], seqs[k], args.batches, args.batch_size, interval,
                               args.resend, random.Random(k), lat, errors, lock, mix, args.vocabulary)
                   for k in range(len(tokens))]
        ends = [f.result() for f in futures]
        stop.set()
        for h in helpers:
            h.result()
    return {"seconds": time.perf_counter() - started, "cpu_s": server.cpu_seconds() - cpu,
            "proxy_cpu_s": server.proxy_cpu_seconds() - proxy_cpu, "client_cpu_s": own_cpu_seconds() - client_cpu,
            "lat": lat,
            "errors": errors, "ends": ends,
            "events": sum(e - s0 for e, s0 in zip(ends, seqs, strict=True)), "suggest_lat": suggest_lat,
            "suggest_errors": suggest_errors}


def measure(stack: Stack, args, mix: list[dict]) -> dict:
    """Enrol the participants, run the paced then the saturated phase; the figures."""
    with ThreadPoolExecutor(max_workers=8) as pool:
        tokens = list(pool.map(lambda i: enrol(stack.base, f"bench-{i}"), range(args.participants)))
    phases = {}
    seqs = [0] * args.participants
    for name, interval in (("paced", args.interval), ("saturated", 0.0)):
        phases[name] = run_phase(stack, tokens, seqs, args, interval, mix,
                                 args.suggest_every if name == "paced" else 0.0)
        seqs = phases[name]["ends"]
    stored, distinct = stack.count()
    sent_total = sum(p["events"] for p in phases.values())
    paced, saturated = phases["paced"], phases["saturated"]
    errors = paced["errors"] + saturated["errors"]
    figures = {
        "database": stack.label,
        "offered_events_per_s": round(args.participants * args.batch_size / args.interval, 1),
        "events_per_s": round(paced["events"] / paced["seconds"], 1),
        "p50_ms": round(percentile(paced["lat"], 50), 1),
        "p95_ms": round(percentile(paced["lat"], 95), 1),
        "p99_ms": round(percentile(paced["lat"], 99), 1),
        "suggest_every_s": args.suggest_every,
        "suggest_requests": len(paced["suggest_lat"]),
        "suggest_p50_ms": round(percentile(paced["suggest_lat"], 50), 1) if paced["suggest_lat"] else None,
        "suggest_p95_ms": round(percentile(paced["suggest_lat"], 95), 1) if paced["suggest_lat"] else None,
        "suggest_errors": len(paced["suggest_errors"]),
        "saturated_events_per_s": round(saturated["events"] / saturated["seconds"], 1),
        "saturated_p95_ms": round(percentile(saturated["lat"], 95), 1),
        "server_cpu_ms_per_1000_events": round(1e6 * saturated["cpu_s"] / saturated["events"], 1),
        "paced_server_cpu_ms_per_1000_events": round(1e6 * paced["cpu_s"] / paced["events"], 1),
        # the load generator shares the machine's cores (two here): its own CPU, beside the server's
        "paced_load_generator_cpu_ms_per_1000_events": round(1e6 * paced["client_cpu_s"] / paced["events"], 1),
        "load_generator_cpu_ms_per_1000_events": round(1e6 * saturated["client_cpu_s"] / saturated["events"], 1),
        "posts": len(paced["lat"]) + len(saturated["lat"]),
        "events_sent": sent_total,
        "events_stored": stored,
        "lost": sent_total - distinct,
        "duplicates": stored - distinct,
        "errors": len(errors),
    }
    if saturated["proxy_cpu_s"]:
        figures["proxy_cpu_ms_per_1000_events"] = round(1e6 * saturated["proxy_cpu_s"] / saturated["events"], 1)
    figures["ok"] = not errors and not paced["suggest_errors"] and stored == sent_total == distinct
    return figures


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--participants", type=int, default=50)
    parser.add_argument("--batches", type=int, default=20, help="batches per participant in each phase")
    parser.add_argument("--batch-size", type=int, default=100)
    parser.add_argument("--interval", type=float, default=1.0,
                        help="seconds between a participant's batches in the paced phase (the client flushes "
                             "its outbox about once a second)")
    parser.add_argument("--resend", type=float, default=0.05, help="fraction of batches sent twice")
    parser.add_argument("--workers", type=int, default=2, help="gunicorn workers per app server")
    parser.add_argument("--vocabulary", type=int, choices=(1, 2), default=2,
                        help="event vocabulary version to send (1: no object states, as pages of that version)")
    parser.add_argument("--suggest-every", type=float, default=5.0,
                        help="seconds between one participant's context queries during the paced phase "
                             "(0: ingestion alone)")
    parser.add_argument("--database", choices=("sqlite", "postgresql"), default="sqlite",
                        help="postgresql: a throwaway server; SQLite is then measured too, in the same run")
    parser.add_argument("--via-proxy", action="store_true",
                        help="with --database postgresql: app servers behind nginx over TLS")
    parser.add_argument("--apps", type=int, default=None,
                        help="app servers on PostgreSQL (default: one, or two behind the proxy)")
    realistic_args = parser.add_argument_group("a realistic crowd (--realistic)")
    realistic_args.add_argument("--realistic", action="store_true",
                                help="participants take the whole study at once, each sending what a simulated "
                                     "person sends when (instead of the paced and saturated phases)")
    realistic_args.add_argument("--pace", type=float, default=1.0,
                                help="times a person's speed (1: as fast as people; the load of pace × "
                                     "participants people)")
    realistic_args.add_argument("--arrival", type=float, default=30.0,
                                help="seconds over which the participants arrive")
    realistic_args.add_argument("--record", type=int, default=12, help="simulated participants recorded")
    realistic_args.add_argument("--full-study", dest="short_study", action="store_false",
                                help="the whole demo study (ten trials) instead of its practice and one scene")
    realistic_args.add_argument("--kill", action="store_true",
                                help="SIGKILL one app server a third of the way in, start it again 3 s later")
    realistic_args.add_argument("--capacity", action="store_true",
                                help="also on SQLite; print participants per app-server core for each")
    realistic_args.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    checkout.require(ROOT)
    if demo_missing():
        print(json.dumps({"benchmark": "ingest", "error": demo_missing()}))
        return 1
    if args.via_proxy and (args.database != "postgresql" or nginx_missing()):
        print(json.dumps({"benchmark": "ingest", "error": nginx_missing() or "--via-proxy needs --database "
                                                                             "postgresql"}))
        return 1
    if args.apps and args.apps > 1 and not args.via_proxy:
        print(json.dumps({"benchmark": "ingest", "error": "--apps above 1 needs --via-proxy (something must spread "
                                                          "the load over them)"}))
        return 1
    if args.realistic and args.kill and args.capacity:
        print(json.dumps({"benchmark": "ingest", "error": "--kill and --capacity apart: a killed server's CPU "
                                                          "cannot be counted"}))
        return 1
    if args.realistic:
        import realistic

        out = realistic.main(args)
        ok = out.pop("ok")
        print(json.dumps(out, indent=1))
        if "capacity" in out:  # the README's table, for this machine
            print(realistic.table_text(out["capacity"]), file=sys.stderr)
        return 0 if ok else 1
    mix = event_mix(args.vocabulary)
    sizes = sorted(len(json.dumps({"seq": 12345, "t": 1.7e12, **e})) for e in mix)
    out = {"benchmark": "ingest", "participants": args.participants, "batch_size": args.batch_size,
           "batch_interval_s": args.interval, "gunicorn_workers": args.workers, "vocabulary": args.vocabulary,
           "median_event_bytes": sizes[len(sizes) // 2], "mean_event_bytes": round(sum(sizes) / len(sizes), 1)}
    with tempfile.TemporaryDirectory() as tmp:
        if args.database == "postgresql":
            with postgres_stack(Path(tmp) / "pg", args.workers, args.via_proxy, apps=args.apps) as stack:
                out |= measure(stack, args, mix)
            with sqlite_stack(Path(tmp) / "sqlite", args.workers) as stack:  # the same load, the same run
                out["sqlite"] = {k: v for k, v in measure(stack, args, mix).items()
                                 if k in SQLITE_BESIDE}
        else:
            with sqlite_stack(Path(tmp), args.workers) as stack:
                out |= measure(stack, args, mix)
    ok = out.pop("ok") and out.get("sqlite", {}).get("ok", True)
    print(json.dumps(out, indent=1))
    return 0 if ok else 1


#: The SQLite figures printed beside PostgreSQL's.
SQLITE_BESIDE = ("events_per_s", "p95_ms", "saturated_events_per_s", "saturated_p95_ms",
                 "server_cpu_ms_per_1000_events", "lost", "errors", "ok")


if __name__ == "__main__":
    sys.exit(main())
