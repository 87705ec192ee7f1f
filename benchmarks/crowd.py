"""A realistic crowd: what one participant sends and how fast (recorded from simulated participants), and a
thousand of them taking the whole study at once over real HTTP, in one process (asyncio, one task per person).

*What a person sends* comes from :class:`simulation.participant.Bot` runs in process: every request of each trial
(the target and start scenes, the model list, the suggestions and searches, the events with the client times of
the simulated person, "done") recorded per condition × scene. The page's outbox (``static/js/outbox.js``) sends
what was logged one second after the first unsent event (at most ``OUTBOX_MAX`` events), so a trial's batches are
its events grouped that way (:func:`outbox_batches`); :func:`shape` gives the rates (events, batches, suggestions
and searches per minute of trial time; batch sizes).

*A crowd* (:func:`run_crowd`): each participant follows the entry link, answers the device check, consent,
demographics and instructions as a browser does (real pages, their form tokens, one cookie jar each), plays each
trial as a recorded trial of the same condition and scene — requests at the recorded times divided by ``pace``,
events renumbered into its own sequence and sent in the outbox's batches, list ids answered by the server put in
the events that name them —, fills in the exit survey and reads its completion code. Like the page, a request
that finds no server (refused, reset, 502, 503, 504) is sent again with backoff, so an app server killed midway
costs retries, never data.
"""

from __future__ import annotations

import asyncio
import json
import random
import re
import ssl
import tempfile
import time
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path

import tests_path  # noqa: F401 (tests/ on the path, for the shared test infrastructure)
from demostudy import DEMOGRAPHICS, make_app
from serverproc import DEMO_STUDY

from simulation.walker import MAX_PAGES

#: The page's outbox: a send one second after the first unsent event, at most this many events per batch.
OUTBOX_DELAY_S = 1.0
OUTBOX_MAX = 200
#: Answers that mean "no server here now" (nginx with its app servers away, a server starting): sent again.
RETRIED = (502, 503, 504)
RETRY_FOR_S = 120.0
#: How often the crowd looks at how late its own timers are (s).
LAG_EVERY_S = 0.05


# -- what a person sends ------------------------------------------------------------------------------------------
@dataclass
class TrialTrace:
    """One recorded trial: ``events`` as the page logged them (client times, ms), the ``suggests`` (request body,
    the list id answered) and ``searches`` (path, list id) in the order made, and the body of "done"."""

    condition: str
    scene: str
    events: list[dict] = field(default_factory=list)
    suggests: list[tuple[dict, str]] = field(default_factory=list)
    searches: list[tuple[str, str]] = field(default_factory=list)
    done: dict | None = None

    @property
    def minutes(self) -> float:
        return (self.events[-1]["t"] - self.events[0]["t"]) / 60000.0 if self.events else 0.0


def record_trials(bots: int, study: Path = DEMO_STUDY, seed: int = 0) -> list[list[TrialTrace]]:
    """The trials of ``bots`` simulated participants taking ``study`` in process (a throwaway database), each
    participant's in order."""
    import numpy as np

    from simulation.participant import Bot
    from simulation.transport import FlaskTransport

    people, name = [], study_id(study)
    with tempfile.TemporaryDirectory() as tmp:
        app = make_app(Path(tmp), studies=[study])
        for k in range(bots):
            transport, trials = FlaskTransport(app.test_client()), {}
            post, get = transport.post, transport.get
            asked = TrialTrace("", "")  # the suggestions and searches of the trial under way ("done" closes it)

            def recording_post(path, form=None, json_body=None, headers=None, post=post, trials=trials, asked=asked):
                r = post(path, form=form, json_body=json_body, headers=headers)
                if path == "/api/events":
                    for e in json_body["events"]:
                        trials.setdefault(e["trial"], TrialTrace("", "")).events.append(e)
                        if e["type"] == "trial_start":
                            trials[e["trial"]].condition = e["payload"]["condition"]
                            trials[e["trial"]].scene = e["payload"]["scene"]
                elif path == "/api/suggest":
                    asked.suggests.append((json_body, r.json()["list_id"]))
                elif path == "/api/trial/done":
                    trial = trials[json_body["trial"]]
                    trial.done, trial.suggests, trial.searches = json_body, asked.suggests, asked.searches
                    asked.suggests, asked.searches = [], []
                return r

            def recording_get(path, headers=None, get=get, asked=asked):
                r = get(path, headers=headers)
                if path.startswith("/api/search"):
                    asked.searches.append((path[len("/api"):], r.json()["list_id"]))
                return r

            transport.post, transport.get = recording_post, recording_get
            Bot(transport, name, f"recorded-{k}", np.random.default_rng(seed + k)).run()
            people.append([trials[i] for i in sorted(trials)])
    return people


def study_id(study: Path) -> str:
    from study_server.studies.study_file import load_study

    return load_study(study).id


def outbox_batches(times_ms: list[float], delay_s: float = OUTBOX_DELAY_S, most: int = OUTBOX_MAX) -> list[list[int]]:
    """The batches the page's outbox sends for events logged at ``times_ms`` (ascending): the first unsent event
    starts a timer of ``delay_s``; when it fires, what is pending goes, ``most`` at a time. Each batch as the
    indices of its events."""
    batches, i = [], 0
    while i < len(times_ms):
        due = times_ms[i] + delay_s * 1000.0
        j = i
        while j < len(times_ms) and times_ms[j] <= due:
            j += 1
        for k in range(i, j, most):
            batches.append(list(range(k, min(j, k + most))))
        i = j
    return batches


def percentile(values, q: float) -> float:
    values = sorted(values)
    return values[min(len(values) - 1, int(round(q / 100 * (len(values) - 1))))] if values else float("nan")


def shape(people: list[list[TrialTrace]]) -> dict:
    """What one participant sends, from recorded trials: per participant, events, event batches, suggestions and
    searches per minute of trial time (median and 95th percentile over participants), the batch sizes (median,
    95th percentile, largest, over all batches) and the minutes a study's trials take."""
    per_minute = {"events": [], "batches": [], "suggestions": [], "searches": []}
    sizes, minutes = [], []
    for trials in people:
        m = sum(t.minutes for t in trials)
        batches = [b for t in trials for b in outbox_batches([e["t"] for e in t.events])]
        sizes += [len(b) for b in batches]
        minutes.append(m)
        for key, n in (("events", sum(len(t.events) for t in trials)), ("batches", len(batches)),
                       ("suggestions", sum(len(t.suggests) for t in trials)),
                       ("searches", sum(len(t.searches) for t in trials))):
            per_minute[key].append(n / m)
    out = {f"{key}_per_min": {"median": round(percentile(v, 50), 1), "p95": round(percentile(v, 95), 1)}
           for key, v in per_minute.items()}
    return out | {"batch_size": {"median": percentile(sizes, 50), "p95": percentile(sizes, 95), "max": max(sizes)},
                  "trial_minutes_per_participant": {"median": round(percentile(minutes, 50), 1),
                                                    "p95": round(percentile(minutes, 95), 1)},
                  "participants_recorded": len(people)}


# -- a crowd ------------------------------------------------------------------------------------------------------
@dataclass
class Tally:
    """What the crowd saw: latencies (ms, from a request's first attempt to its answer, retries included) by kind
    of request, retries by cause, failures, codes, events acknowledged, the person-time played."""

    participants: int = 0
    latency: dict[str, list[float]] = field(default_factory=dict)
    #: the same, of the requests sent once every participant has reached a first trial (``settled_at``, monotonic)
    settled: dict[str, list[float]] = field(default_factory=dict)
    settled_at: float = float("inf")
    #: the same moment as wall-clock time (epoch s), to split the server's own log
    settled_epoch: float = float("inf")
    #: the load generator's own delays: (when, monotonic; ms late) of a timer due every LAG_EVERY_S — a crowd that
    #: cannot keep up with itself measures its own lateness as the server's latency
    lag: list[tuple[float, float]] = field(default_factory=list)
    #: participants who have reached a first trial
    arrived: int = 0
    #: attempts sent again, by cause: "no server" (refused, reset, timed out; nginx's 502 and 504) or the app's
    #: own "503" (its database away or locked, suggestions unavailable)
    retries: Counter = field(default_factory=Counter)
    failures: list[str] = field(default_factory=list)
    codes: dict[str, str | None] = field(default_factory=dict)
    #: per participant, the highest seq the server acknowledged (every event up to it stored, said the server)
    acked: dict[str, int] = field(default_factory=dict)
    #: minutes of a person's trial time played (the recorded trials' lengths), over all participants
    person_minutes: float = 0.0


class Person:
    """One participant of the crowd: an HTTP session of its own (cookies, connections) against ``base``."""

    def __init__(self, session, base: str, study: str, pid: str, pace: float, tally: Tally, rng: random.Random):
        self.http, self.base, self.study, self.pid = session, base, study, pid
        self.pace, self.tally, self.rng = pace, tally, rng
        self.seq = 0
        self.models_fetched = False

    async def request(self, kind: str, method: str, path: str, **kw) -> tuple[int, bytes]:
        """Send, again with backoff while no server answers or the app answers 503 (as the page does); the status
        and body of the answer. Its latency, from the first attempt on, is counted under ``kind``."""
        import aiohttp

        first = time.monotonic()
        deadline, wait = first + RETRY_FOR_S, 0.1
        while True:
            try:
                async with self.http.request(method, self.base + path, **kw) as r:
                    body = await r.read()
                    status = r.status
            except (TimeoutError, aiohttp.ClientError) as e:
                status, body = None, str(e).encode()
            if status is not None and status not in RETRIED:
                ms = (time.monotonic() - first) * 1000.0
                self.tally.latency.setdefault(kind, []).append(ms)
                if first >= self.tally.settled_at:
                    self.tally.settled.setdefault(kind, []).append(ms)
                return status, body
            if time.monotonic() > deadline:
                raise RuntimeError(f"{method} {path}: no answer for {RETRY_FOR_S:.0f} s ({status})")
            # nginx answers 502/504 itself, in HTML, when no app server does; the app's 503 is JSON
            app_said = status == 503 and body.lstrip().startswith(b"{")
            self.tally.retries["503" if app_said else "no server"] += 1
            await asyncio.sleep(wait * self.rng.uniform(0.5, 1.5))
            wait = min(wait * 2, 2.0)

    async def page(self, method: str, path: str, form: dict | None = None):
        from simulation.page import read_page

        status, body = await self.request("page", method, f"/study/{self.study}{path}", data=form)
        if status >= 400:
            raise RuntimeError(f"{method} {path} → {status}")
        return read_page(body)

    async def api(self, kind: str, method: str, path: str, token: str, body=None) -> dict:
        headers = {"Authorization": f"Bearer {token}"}
        if body is not None:
            headers["Content-Type"] = "application/json"
        status, answer = await self.request(kind, method, f"/api{path}", headers=headers,
                                            data=None if body is None else json.dumps(body))
        if status != 200:
            raise RuntimeError(f"{method} /api{path} → {status}: {answer[:200]!r}")
        return json.loads(answer)

    async def run(self, recorded: dict[tuple[str, str], list[TrialTrace]]) -> None:
        """The whole study: entry link to completion code."""
        page = await self.page("GET", f"/start?pid={self.pid}")
        for _ in range(MAX_PAGES):
            if page.step == "done":
                self.tally.codes[self.pid] = page.code
                return
            if page.step == "saving":  # the exit survey waits for events the server does not have: lost
                raise RuntimeError("the exit survey waits for events the server never acknowledged")
            if page.step == "trial":
                await self.play(page.boot, self.rng.choice(recorded[page.boot["trial"]["condition"],
                                                                    page.boot["trial"]["scene"]]))
                page = await self.page("GET", "/")
                continue
            form = _answers(page, self.seq)
            page = await self.page("POST", f"/{page.step}", {"csrf_token": page.csrf or "", **form})
        raise RuntimeError("the study never ended")

    async def play(self, boot: dict, trace: TrialTrace) -> None:
        """One trial as ``trace`` was played, at ``pace`` times a person's speed."""
        token, index = boot["token"], boot["trial"]["index"]
        if self.pid not in self.tally.acked:  # a first trial: this participant has arrived
            self.tally.acked[self.pid] = -1
            self.tally.arrived += 1
            if self.tally.arrived == self.tally.participants:
                self.tally.settled_at, self.tally.settled_epoch = time.monotonic(), time.time()
        for which in ("target", "start"):
            await self.api("scene", "GET", f"/scenes/{boot['trial']['scene']}?which={which}", token)
        if not self.models_fetched:
            await self.api("models", "GET", "/models", token)
            self.models_fetched = True
        lists: dict[str, str] = {}  # recorded list id → the one the server gave this participant
        suggests, searches = iter(trace.suggests), iter(trace.searches)
        t0, started = trace.events[0]["t"], time.monotonic()
        pending: list[dict] = []
        due = None  # when the outbox sends what is pending

        async def send():
            nonlocal pending, due
            while pending:
                batch, pending = pending[:OUTBOX_MAX], pending[OUTBOX_MAX:]
                body = {"page_id": boot["page_id"], "vocabulary": boot["vocabulary"], "events": batch}
                acked = (await self.api("events", "POST", "/events", token, body))["acked_seq"]
                if acked != batch[-1]["seq"]:
                    raise RuntimeError(f"events up to {batch[-1]['seq']} sent, {acked} acknowledged")
                self.tally.acked[self.pid] = acked
            due = None

        for e in trace.events:
            at = started + (e["t"] - t0) / 1000.0 / self.pace
            if due is not None and due <= at:
                await _sleep_until(due)
                await send()
            await _sleep_until(at)
            payload = dict(e["payload"])
            if payload.get("list_id") is not None:  # a list this participant was shown, under the server's id
                payload["list_id"] = lists[payload["list_id"]]
            pending.append({"seq": self.seq, "t": time.time() * 1000.0, "type": e["type"], "trial": index,
                            "payload": payload})
            self.seq += 1
            if due is None:  # a second of the person's time after the first unsent event
                due = time.monotonic() + OUTBOX_DELAY_S / self.pace
            if e["type"] == "context_query":
                body, recorded_id = next(suggests)
                answer = await self.api("suggest", "POST", "/suggest", token, {**body, "trial": index})
                lists[recorded_id] = answer["list_id"]
            elif e["type"] == "search":
                path, recorded_id = next(searches)
                lists[recorded_id] = (await self.api("search", "GET", path, token))["list_id"]
        await send()
        await self.api("done", "POST", "/trial/done", token, {**trace.done, "trial": index, "last_seq": self.seq - 1})
        self.tally.person_minutes += trace.minutes


async def _sleep_until(at: float) -> None:
    delay = at - time.monotonic()
    if delay > 0:
        await asyncio.sleep(delay)


def _answers(page, seq: int) -> dict:
    """A form's answers: the fixed ones of the walk, the demographics of the benchmarks, the exit survey's first
    choices (with the last event's seq, as the page sends it)."""
    from simulation.walker import fixed_answer

    fixed = fixed_answer(page)
    if fixed is not None:
        return fixed
    if page.step == "demographics":
        return DEMOGRAPHICS
    if page.step == "exit":
        return {**{q: values[0] for q, values in page.radios.items()},
                **{q: str(int(low)) for q, (low, _) in page.numbers.items()}, **{q: "" for q in page.texts},
                "last_seq": str(seq - 1), "attempt": "0"}
    raise RuntimeError(f"a page the crowd cannot go on from (step {page.step!r})")


async def _crowd(base: str, study: str, participants: int, pace: float, arrival_s: float,
                 recorded: dict, tally: Tally, cafile: str | None, seed: int, during=None) -> None:
    import aiohttp

    context = ssl.create_default_context(cafile=cafile) if base.startswith("https") else None

    async def one(i: int):
        rng = random.Random(seed * 100003 + i)
        await asyncio.sleep(rng.uniform(0, arrival_s))
        # a browser's connections: its own, kept alive, at most six to the server
        connector = aiohttp.TCPConnector(limit=6, ssl=context if context else False)
        timeout = aiohttp.ClientTimeout(total=60)
        async with aiohttp.ClientSession(connector=connector, timeout=timeout,
                                         cookie_jar=aiohttp.CookieJar(unsafe=True)) as session:
            pid = f"crowd-{seed}-{i}"
            try:
                await Person(session, base, study, pid, pace, tally, rng).run(recorded)
            except Exception as e:  # counted: the run fails, the others go on
                tally.failures.append(f"{pid}: {e}")

    async def watch():
        while True:
            due = time.monotonic() + LAG_EVERY_S
            await asyncio.sleep(LAG_EVERY_S)
            tally.lag.append((due, (time.monotonic() - due) * 1000.0))

    tasks = [asyncio.create_task(one(i)) for i in range(participants)]
    if during is not None:
        tasks.append(asyncio.create_task(during()))
    watcher = asyncio.create_task(watch())
    try:
        await asyncio.gather(*tasks)
    finally:
        watcher.cancel()


def run_crowd(base: str, study: str, participants: int, people: list[list[TrialTrace]], pace: float = 1.0,
              arrival_s: float = 30.0, cafile: str | None = None, seed: int = 0, during=None) -> Tally:
    """``participants`` take ``study`` at ``base`` at once (arriving over ``arrival_s`` seconds), each playing
    recorded trials (``people``, from :func:`record_trials`) at ``pace`` times a person's speed. ``during``: a
    coroutine function run beside them (a fault to inject). Returns the :class:`Tally`."""
    recorded: dict[tuple[str, str], list[TrialTrace]] = {}
    for trials in people:
        for t in trials:
            if t.events and t.done is not None:
                recorded.setdefault((t.condition, t.scene), []).append(t)
    tally = Tally(participants)
    asyncio.run(_crowd(base, study, participants, pace, arrival_s, recorded, tally, cafile, seed, during))
    return tally


def bench_study(folder: Path, scenes: tuple[str, ...] | None = ("desk-corner",), arrivals: int = 100_000) -> Path:
    """The demo study for a crowd: with only the practice and ``scenes`` as targets (each condition once per
    scene: the whole study path in a few minutes of a person's time; None: every scene), and a quota of
    ``arrivals`` new participants per address and hour (a crowd on loopback arrives from one address, a real one
    from as many as it has people). Written into ``folder`` beside a link to the demo's scenes."""
    text = DEMO_STUDY.read_text()
    if scenes is not None:
        kept = {"practice", *scenes}
        blocks = re.split(r"(?m)^(?=\[)", text)  # a block per table, from its header to the next
        text = "".join(b for b in blocks if not b.startswith("[[scenes]]") or
                       re.search(r'(?m)^id = "([^"]+)"', b).group(1) in kept)
        text = re.sub(r"(?m)^scenes = \[[^\]]*\]$", "scenes = [" + ", ".join(f'"{s}"' for s in scenes) + "]", text)
    text, n = re.subn(r"(?m)^arrivals_per_address_per_hour = \d+$", f"arrivals_per_address_per_hour = {arrivals}",
                      text)
    if n != 1:
        raise RuntimeError(f"{DEMO_STUDY} sets no arrivals_per_address_per_hour to raise")
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "scenes").symlink_to(DEMO_STUDY.parent / "scenes")
    (folder / "study.toml").write_text(text)
    return folder / "study.toml"
