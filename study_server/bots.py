"""Simulated participants: bots that take part in a study through its HTTP interface alone.

A bot walks the whole flow (entry link, device check, consent, demographics, instructions, every trial, exit
survey) and in each trial rebuilds the target scene the way a person would: in ``basic``/``full`` it asks for
suggestions at each target object's contact point on its parent and picks the object's model at the rank the
engine really gave it (searching by keyword when it is absent); in ``none`` it scans the fixed model list or
searches. It then moves and turns the object until its pose matches the target.

Time is not slept but simulated: each action costs the operator times of the keystroke-level model (Card, Moran
& Newell 1980: K keystroke 0.28 s, P point 1.1 s, B button 0.1 s, M mental preparation 1.35 s), list scanning
costs per item looked at, drags follow Fitts' law, and a participant-level speed factor varies them. The events
carry these simulated client times, so the analysis sees how long a person would have taken given what the
engine returned — condition differences come from the engine's ranks and orientations, not from typed-in
effect sizes.
"""

from __future__ import annotations

import json
import math
import re
from dataclasses import dataclass, field
from html import unescape
from html.parser import HTMLParser

import numpy as np

from scenesuggest import poses
from scenesuggest.symmetry import glb_symmetry_period_deg, visible_turn_deg

#: Keystroke-level model operators, seconds (Card, Moran & Newell 1980).
K, P, B, M = 0.28, 1.1, 0.1, 1.35
SCAN_PER_ITEM = 0.35  # looking at one thumbnail of a list, s
LIST_VISIBLE = 24  # items a person scans before giving up on the list and searching
FITTS_A, FITTS_B, TARGET_M = 0.2, 0.15, 0.05  # drag time = a + b log2(d / w + 1)
COARSE_DEG, POSE_TOLERANCE_DEG, POSE_TOLERANCE_M = 15.0, 4.0, 0.03
#: Where a click for a new object lands: the intended contact point plus a random error in the surface plane
#: (standard deviation, m), at most a tenth of the support's smaller side; the object is then dragged into place.
CLICK_ERROR_M = 0.15


class FlowError(RuntimeError):
    """The server answered something a participant's browser would not have expected."""


@dataclass
class Response:
    status: int
    body: bytes

    @property
    def text(self) -> str:
        return self.body.decode(errors="replace")

    def json(self):
        return json.loads(self.body)


class FlaskTransport:
    """Requests through a Flask test client (in-process; cookies kept by the client)."""

    def __init__(self, client):
        self.client = client

    def get(self, path, headers=None) -> Response:
        r = self.client.get(path, headers=headers or {}, follow_redirects=True)
        return Response(r.status_code, r.get_data())

    def post(self, path, form=None, json_body=None, headers=None) -> Response:
        r = self.client.post(path, data=form, json=json_body, headers=headers or {}, follow_redirects=True)
        return Response(r.status_code, r.get_data())


class HttpTransport:
    """Real HTTP to a running server (urllib, a cookie jar per participant, redirects followed).

    Like the browser's outbox, a request that finds no server (refused, reset, timed out, 502/503) is retried
    with backoff for up to ``retry_for`` seconds; every request the bots make is safe to repeat (events are
    idempotent by sequence number, flow steps by the participant's state)."""

    def __init__(self, base_url: str, timeout: float = 30.0, retry_for: float = 0.0):
        import http.cookiejar
        import urllib.request

        self.base = base_url.rstrip("/")
        self.timeout, self.retry_for = timeout, retry_for
        self.retries = 0
        self.opener = urllib.request.build_opener(urllib.request.HTTPCookieProcessor(http.cookiejar.CookieJar()))

    def _send(self, method, path, data=None, headers=None) -> Response:
        import http.client
        import time
        import urllib.error
        import urllib.request

        deadline, wait = time.monotonic() + self.retry_for, 0.1
        while True:
            req = urllib.request.Request(self.base + path, data=data, method=method, headers=headers or {})
            try:
                with self.opener.open(req, timeout=self.timeout) as r:
                    return Response(r.status, r.read())
            except urllib.error.HTTPError as e:
                response = Response(e.code, e.read())
                if e.code not in (502, 503) or time.monotonic() > deadline:
                    return response
            except (urllib.error.URLError, http.client.HTTPException, ConnectionError, TimeoutError) as e:
                if time.monotonic() > deadline:
                    raise FlowError(f"{method} {path}: no server ({e})") from None
            self.retries += 1
            time.sleep(wait)
            wait = min(wait * 2, 2.0)

    def get(self, path, headers=None) -> Response:
        return self._send("GET", path, headers=headers)

    def post(self, path, form=None, json_body=None, headers=None) -> Response:
        from urllib.parse import urlencode

        headers = dict(headers or {})
        if json_body is not None:
            headers["Content-Type"] = "application/json"
            return self._send("POST", path, json.dumps(json_body).encode(), headers)
        headers["Content-Type"] = "application/x-www-form-urlencoded"
        return self._send("POST", path, urlencode(form or {}).encode(), headers)


class LossyTransport:
    """A slow network that loses things: with probability ``loss`` a request never arrives, and with the same
    probability its response is lost after the server acted on it (a timeout); either way the bot sends it
    again, as a browser's retry or a participant's reload would. Every request must therefore be safe to repeat."""

    def __init__(self, inner, rng: np.random.Generator, loss: float, latency_s: float = 0.0):
        self.inner, self.rng, self.loss, self.latency_s = inner, rng, loss, latency_s
        self.lost = 0

    def _retry(self, send) -> Response:
        if self.latency_s:  # a slow network: each round trip waits (real time)
            import time

            time.sleep(float(self.rng.exponential(self.latency_s)))
        while self.rng.random() < self.loss:  # the request is lost on the way
            self.lost += 1
        response = send()
        while self.rng.random() < self.loss:  # the server acted, the answer is lost: send again
            self.lost += 1
            response = send()
        return response

    def get(self, path, headers=None) -> Response:
        return self._retry(lambda: self.inner.get(path, headers))

    def post(self, path, form=None, json_body=None, headers=None) -> Response:
        return self._retry(lambda: self.inner.post(path, form=form, json_body=json_body, headers=headers))

    @property
    def retries(self) -> int:
        return getattr(self.inner, "retries", 0) + self.lost


class _Form(HTMLParser):
    """The fields of a survey page: radio groups with their values, number inputs, text areas, hidden inputs."""

    def __init__(self):
        super().__init__()
        self.radios: dict[str, list[str]] = {}
        self.numbers: dict[str, tuple[float, float]] = {}
        self.texts: list[str] = []
        self.hidden: dict[str, str] = {}

    def handle_starttag(self, tag, attrs):
        a = dict(attrs)
        if tag == "input" and a.get("type") == "radio":
            self.radios.setdefault(a["name"], []).append(a.get("value", ""))
        elif tag == "input" and a.get("type") == "number":
            self.numbers[a["name"]] = (float(a.get("min", 0)), float(a.get("max", 99)))
        elif tag == "input" and a.get("type") == "hidden":
            self.hidden[a["name"]] = a.get("value", "")
        elif tag == "textarea":
            self.texts.append(a["name"])


def _boot(text: str) -> dict | None:
    m = re.search(r'<script type="application/json" id="boot">(.*?)</script>', text, re.S)
    return json.loads(unescape(m.group(1))) if m else None


def heading_deg(transform: list[float]) -> float:
    """Heading of a column-major 4×4 transform: the angle of its front (+Z) about +Y, degrees."""
    return math.degrees(math.atan2(transform[8], transform[10]))


def rotation_of(transform: list[float]) -> np.ndarray:
    """The 3×3 rotation of a column-major 4×4 rigid transform."""
    return np.asarray(transform, dtype=float).reshape(4, 4).T[:3, :3]


def canonical_pose(obj: dict) -> tuple[np.ndarray, np.ndarray]:
    """Where the list and search place an object at its click point: its attachment face on the surface, not
    turned (α = 0); returns the origin (metres, world) and the 3×3 rotation."""
    t = poses.placement(obj["click"], obj["contact_normal"], obj["attachment_face"], obj["size"], 0.0)
    return t[:3, 3], t[:3, :3]


def words(category: str) -> str:
    """The search text a person would type for a category: ``DeskLamp`` → ``desk lamp``."""
    return re.sub(r"(?<=[a-z])(?=[A-Z])", " ", category).lower()


@dataclass(frozen=True)
class Behaviours:
    """How often a bot does what real participants do to a server (all off by default).

    ``reload`` and ``second_tab``: per trial, the page is opened again midway (the trial resumes there);
    ``duplicate_arrival``: per participant, the entry link is followed again after the first trial;
    ``resend``: per batch, the events are posted twice (a lost acknowledgement); ``drop_out``: per participant,
    the bot leaves after a random trial and never finishes; ``lossy``: per request, lost on the way or its
    answer lost after the server acted (see :class:`LossyTransport`); ``latency_s``: mean extra seconds per round
    trip (a slow network, real waiting)."""

    reload: float = 0.0
    second_tab: float = 0.0
    duplicate_arrival: float = 0.0
    resend: float = 0.0
    drop_out: float = 0.0
    lossy: float = 0.0
    latency_s: float = 0.0

    @classmethod
    def mixed(cls) -> Behaviours:
        return cls(reload=0.1, second_tab=0.05, duplicate_arrival=0.2, resend=0.1, drop_out=0.1, lossy=0.05)


@dataclass
class BotResult:
    pid: str
    code: str | None = None
    dropped_out: bool = False
    reloads: int = 0
    events: int = 0
    trials: int = 0
    missing_objects: int = 0
    condition_seconds: dict[str, list[float]] = field(default_factory=dict)


class Bot:
    """One simulated participant; ``speed`` scales every operator time (1 = the model's average person)."""

    def __init__(self, transport, study: str, pid: str, rng: np.random.Generator, speed: float | None = None,
                 behaviours: Behaviours | None = None, symmetry: dict[str, float] | None = None):
        self.http, self.study, self.pid, self.rng = transport, study, pid, rng
        #: model id → symmetry period (deg), shared between bots: a person sees that a vase needs no turning
        self.symmetry = symmetry if symmetry is not None else {}
        self.library: dict[str, dict] = {}
        self.speed = speed if speed is not None else float(rng.lognormal(0.0, 0.25))
        self.does = behaviours or Behaviours()
        if self.does.lossy or self.does.latency_s:
            self.http = LossyTransport(transport, rng, self.does.lossy, self.does.latency_s)
        # how often this person overlooks the wanted model in a list (mean 0.2): then they search instead
        self.overlook = float(rng.beta(2.0, 8.0))
        self.seq = 0
        self.result = BotResult(pid)

    # -- time -------------------------------------------------------------------------------------------------
    def spend(self, seconds: float) -> None:
        spent = seconds * self.speed * float(self.rng.lognormal(0.0, 0.15))
        self.clock += spent * 1000.0
        self.elapsed += spent

    def overlooks(self) -> bool:
        return self.rng.random() < self.overlook

    def chance(self, rate: float) -> bool:
        """A behaviour happens (no random draw at all when it is off, so plain runs stay reproducible)."""
        return bool(rate) and self.rng.random() < rate

    def event(self, kind: str, payload: dict) -> None:
        self.batch.append({"seq": self.seq, "t": self.clock, "type": kind, "trial": self.trial["index"],
                           "payload": payload})
        self.seq += 1

    # -- the participant flow -----------------------------------------------------------------------------------
    def page(self) -> Response:
        r = self.http.get(f"/study/{self.study}/")
        if r.status >= 400:
            raise FlowError(f"GET /study/{self.study}/ → {r.status}")
        return r

    def post_form(self, step: str, form: dict, page: str) -> Response:
        """Submit a form of ``page`` (the text of the page just shown, which carries the form's CSRF token)."""
        token = re.search(r'name="csrf_token" value="([^"]+)"', page)
        r = self.http.post(f"/study/{self.study}/{step}", form={"csrf_token": token.group(1) if token else "", **form})
        if r.status >= 400:
            raise FlowError(f"POST {step} → {r.status}")
        return r

    def run(self) -> BotResult:
        r = self.http.get(f"/study/{self.study}/start?pid={self.pid}")
        if r.status >= 400:
            raise FlowError(f"entry link → {r.status}")
        leave_after = int(self.rng.integers(1, 9)) if self.chance(self.does.drop_out) else None
        arrive_again = self.chance(self.does.duplicate_arrival)
        for _ in range(200):
            text = self.page().text
            boot = _boot(text)
            if boot is not None:
                self.do_trial(boot)
                if arrive_again and self.result.trials == 1:
                    arrive_again = False
                    if self.http.get(f"/study/{self.study}/start?pid={self.pid}").status >= 400:
                        raise FlowError("entry link followed again → error")
                if leave_after is not None and self.result.trials >= leave_after:
                    self.result.dropped_out = True
                    return self.result
            elif 'name="width"' in text:
                self.post_form("device", {"width": "1440", "height": "900"}, text)
            elif 'name="agree"' in text:
                self.post_form("consent", {"agree": "yes"}, text)
            elif 'id="exit-form"' in text:
                self.survey("exit", text)
            elif 'class="survey"' in text:
                self.survey("demographics", text)
            elif 'name="go"' in text:
                self.post_form("instructions", {"go": "next"}, text)
            else:
                code = re.search(r'class="code">([^<]+)<', text)
                self.result.code = code.group(1) if code else None
                return self.result
        raise FlowError("the study never ended")

    def survey(self, name: str, text: str) -> None:
        form = _Form()
        form.feed(text)
        times = {c: float(np.mean(v)) for c, v in self.result.condition_seconds.items()}
        fastest = min(times, key=times.get) if times else None
        order = ["none", "basic", "full"]
        answers = {}
        for q, values in form.radios.items():
            if q == "preference" and fastest in order and order.index(fastest) < len(values):
                answers[q] = values[order.index(fastest)]
            elif all(v.isdigit() for v in values):
                # suggestions rated higher when they were faster for this participant
                lift = 1 if ("suggest" in q) == (fastest in ("basic", "full")) else -1
                mid = (len(values) + 1) / 2 + lift * 0.8 + self.rng.normal(0, 0.7)
                answers[q] = str(int(np.clip(round(mid), 1, len(values))))
            else:
                answers[q] = values[int(self.rng.integers(len(values)))]
        for q, (low, high) in form.numbers.items():
            answers[q] = str(int(self.rng.integers(int(max(low, 18)), int(min(high, 70)) + 1)))
        for q in form.texts:
            answers[q] = ""
        if name == "exit":
            answers |= {"last_seq": str(self.seq - 1), "attempt": "0"}
        self.post_form(name, answers, text)

    # -- a trial --------------------------------------------------------------------------------------------------
    def api(self, method: str, path: str, body=None) -> dict:
        headers = {"Authorization": f"Bearer {self.token}"}
        r = (self.http.get(f"/api{path}", headers=headers) if method == "GET" else
             self.http.post(f"/api{path}", json_body=body, headers=headers))
        if r.status >= 400:
            raise FlowError(f"{method} /api{path} → {r.status}: {r.text[:200]}")
        return r.json()

    def do_trial(self, boot: dict) -> None:
        import time

        self.token, self.trial, self.page_id = boot["token"], boot["trial"], boot["page_id"]
        self.batch: list[dict] = []
        self.clock = time.time() * 1000.0  # client time, ms since the epoch
        self.elapsed = 0.0  # simulated seconds of this trial (independent of the wall clock)
        index, condition = self.trial["index"], self.trial["condition"]
        target = self.api("GET", f"/scenes/{self.trial['scene']}?which=target")
        start = self.api("GET", f"/scenes/{self.trial['scene']}?which=start")
        present = {o["id"] for o in start["objects"]}
        self.scene = [dict(o) for o in start["objects"]]
        self.event("trial_start", {"scene": self.trial["scene"], "condition": condition})
        if not self.library:  # the study's models, once per session
            self.fixed = self.api("GET", "/models")["models"]
            self.library = {m["id"]: m for m in self.fixed}
        todo = [o for o in target["objects"] if o["id"] not in present]
        reopen_at = len(todo) // 2 if (self.chance(self.does.reload) or self.chance(self.does.second_tab)) else None
        in_scene = {o["id"] for o in self.scene}
        for k, obj in enumerate(todo):
            if k == reopen_at:
                self.reopen()
            if obj["parent"] not in in_scene:  # its support could not be found: nothing to stand it on
                self.result.missing_objects += 1
                continue
            self.spend(M)  # find the next object in the target view
            if self.place(obj, condition):
                self.scene.append(dict(obj))
                in_scene.add(obj["id"])
            else:
                self.result.missing_objects += 1
        self.spend(M + P + B + P + B)  # "done", then confirm
        self.event("trial_done", {"objects": len(self.scene) - len(present)})
        self.flush()
        self.api("POST", "/trial/done", {"trial": index, "scene": {"objects": self.scene}})
        if self.trial["kind"] == "trial":
            self.result.trials += 1
            self.result.condition_seconds.setdefault(condition, []).append(self.elapsed)

    def reopen(self) -> None:
        """The page is loaded again (reload or a second tab): what was logged is sent, the trial resumes."""
        self.flush()
        boot = _boot(self.page().text)
        if boot is None or boot["trial"]["index"] != self.trial["index"]:
            raise FlowError("the reopened page did not resume the trial")
        self.page_id = boot["page_id"]
        self.result.reloads += 1
        self.event("resume", {"reason": "reload"})

    def flush(self) -> None:
        for i in range(0, len(self.batch), 200):
            chunk = self.batch[i:i + 200]
            if self.chance(self.does.resend):
                self.api("POST", "/events", {"page_id": self.page_id, "events": chunk})
            acked = self.api("POST", "/events", {"page_id": self.page_id, "events": chunk})["acked_seq"]
            if acked != chunk[-1]["seq"]:
                raise FlowError(f"events up to {chunk[-1]['seq']} sent, {acked} acknowledged")
        self.result.events += len(self.batch)
        self.batch = []

    def search(self, text: str) -> dict:
        self.spend(M + P + B + K * len(text))
        self.event("search", {"text": text})
        found = self.api("GET", f"/search?q={text.replace(' ', '+')}")
        self.event("list_shown", {"source": "search", "items": [h["id"] for h in found["hits"]],
                                  "list_id": found["list_id"]})
        return found

    def find_by_search(self, obj: dict) -> tuple[int, str] | None:
        """Search for the category's words, then for the model's name (what a person reads in the list)."""
        name = self.library.get(obj["model_id"], {}).get("name", "")
        for text in dict.fromkeys(t for t in (words(obj["category"]), name.lower()) if t):
            found = self.search(text)
            ids = [h["id"] for h in found["hits"]]
            if obj["model_id"] in ids:
                rank = ids.index(obj["model_id"]) + 1
                self.spend(SCAN_PER_ITEM * rank + P + B)
                return rank, found["list_id"]
        return None

    def click_point(self, obj: dict) -> list[float]:
        """Where the click that places ``obj`` lands: near its contact point, on the same support plane."""
        n = np.asarray(obj["contact_normal"], dtype=float)
        n /= np.linalg.norm(n)
        u = np.cross(n, [0.0, 1.0, 0.0] if abs(n[1]) < 0.9 else [1.0, 0.0, 0.0])
        u /= np.linalg.norm(u)
        v = np.cross(n, u)
        parent = next(o for o in self.scene if o["id"] == obj["parent"])
        linear = rotation_of(parent["transform"]) * np.asarray(parent["size"], dtype=float)  # columns: world edges
        extent = np.abs(linear).sum(axis=1)  # the parent's world box size along x, y, z
        side = min(float(np.abs(u) @ extent), float(np.abs(v) @ extent))
        du, dv = self.rng.normal(0.0, min(CLICK_ERROR_M, side / 10), 2)
        return (np.asarray(obj["contact_point"], dtype=float) + du * u + dv * v).tolist()

    def place(self, obj: dict, condition: str) -> bool:
        """Bring one target object into the scene; returns False when the bot could not find its model."""
        obj = {**obj, "click": self.click_point(obj)}
        pose = self.place_from_list(obj) if condition == "none" else self.place_from_suggestions(obj)
        if pose is None:
            return False
        position, placed = pose
        self.adjust(obj, position, placed)
        return True

    def place_from_list(self, obj: dict):
        ids = [m["id"] for m in self.fixed]
        if obj["model_id"] in ids and ids.index(obj["model_id"]) < LIST_VISIBLE and not self.overlooks():
            rank = ids.index(obj["model_id"]) + 1
            self.spend(SCAN_PER_ITEM * rank + P + B)
            source, list_id = "fixed", None
        else:
            self.spend(SCAN_PER_ITEM * LIST_VISIBLE)  # looked, did not see it
            found = self.find_by_search(obj)
            if found is None:
                return None
            (rank, list_id), source = found, "search"
        self.spend(P + B)  # click the surface where it goes
        self.event("insert", {"object": obj["id"], "model": obj["model_id"], "category": obj["category"],
                              "rank": rank, "source": source, "list_id": list_id})
        return canonical_pose(obj)

    def place_from_suggestions(self, obj: dict):
        self.spend(P + K + B)  # shift-click the contact point
        body = {"trial": self.trial["index"], "scene": {"objects": self.scene}, "parent": obj["parent"],
                "point": obj["click"], "normal": obj["contact_normal"]}
        self.event("context_query", {"parent": obj["parent"], "point": obj["click"],
                                     "normal": obj["contact_normal"]})
        found = self.api("POST", "/suggest", body)
        items = found["suggestions"]
        self.event("list_shown", {"source": "context", "items": [i["category"] for i in items],
                                  "list_id": found["list_id"]})
        if not items:
            found = self.find_by_search(obj)
            return None if found is None else self._chosen(obj, found[0], "search", found[1], None)
        top = items[0]
        placed = f"{obj['id']}~s"
        self.event("insert", {"object": placed, "model": top["models"][0]["id"], "category": top["category"],
                              "rank": 1, "source": "context", "list_id": found["list_id"]})
        for item in items:
            ids = [m["id"] for m in item["models"]]
            if obj["model_id"] in ids and not self.overlooks():
                rank = item["rank"]
                self.spend(SCAN_PER_ITEM * rank)
                if ids.index(obj["model_id"]) > 0:  # expand the category and pick the model
                    self.spend(P + B + SCAN_PER_ITEM * (ids.index(obj["model_id"]) + 1))
                matrix = item["placement"]
                orientation = rotation_of(matrix)  # the condition's pose: oriented in full, canonical in basic
                if rank == 1 and ids.index(obj["model_id"]) == 0:
                    self._rename(placed, obj["id"])
                else:
                    self.spend(P + B)
                    self.event("replace", {"object": obj["id"], "replaces": placed, "model": obj["model_id"],
                                           "category": obj["category"], "rank": rank, "source": "context",
                                           "list_id": found["list_id"]})
                return matrix[12:15], orientation
        self.spend(SCAN_PER_ITEM * len(items))
        searched = self.find_by_search(obj)
        if searched is None:
            self.spend(P + B)
            self.event("delete", {"object": placed})
            return None
        return self._chosen(obj, searched[0], "search", searched[1], placed)

    def _rename(self, placed: str, final: str) -> None:
        for e in self.batch:
            if e["payload"].get("object") == placed:
                e["payload"]["object"] = final

    def _chosen(self, obj, rank, source, list_id, replaces):
        kind = "replace" if replaces else "insert"
        payload = {"object": obj["id"], "model": obj["model_id"], "category": obj["category"], "rank": rank,
                   "source": source, "list_id": list_id}
        if replaces:
            payload["replaces"] = replaces
        self.event(kind, payload)
        return canonical_pose(obj)

    def period_of(self, model_id: str) -> float:
        """How far the model can be turned before it looks different (from its mesh, as the browser shows it)."""
        if model_id not in self.symmetry:
            model = self.library.get(model_id)
            r = self.http.get(model["asset"]) if model else None
            self.symmetry[model_id] = glb_symmetry_period_deg(r.body) if r is not None and r.status == 200 else 360.0
        return self.symmetry[model_id]

    def adjust(self, obj: dict, position, placed: np.ndarray) -> None:
        """Drag to the target position, then turn from the placed orientation (3×3) to the target's about the
        support normal."""
        distance = float(np.linalg.norm(np.subtract(position, obj["transform"][12:15])))
        if distance > POSE_TOLERANCE_M:
            self.spend(M + P)
            self.event("move_start", {"object": obj["id"]})
            self.spend(B + FITTS_A + FITTS_B * math.log2(distance / TARGET_M + 1) + B)
            self.event("move_end", {"object": obj["id"], "distance": distance, "parent": obj["parent"]})
        turn = math.degrees(poses.turn_about(placed, rotation_of(obj["transform"]), obj["contact_normal"]))
        if abs(obj["contact_normal"][1]) > 0.9:  # on a floor or a table: only a visible difference is turned
            turn = visible_turn_deg(turn, self.period_of(obj["model_id"]))
        if abs(turn) > POSE_TOLERANCE_DEG:
            coarse = round(abs(turn) / COARSE_DEG)
            fine = abs(abs(turn) - coarse * COARSE_DEG)
            self.spend(M + P + B)  # select it and think about the turn
            self.event("rotate_start", {"object": obj["id"]})
            self.spend(K * coarse + (M + K * round(fine) if fine > POSE_TOLERANCE_DEG else 0.0))
            self.event("rotate_end", {"object": obj["id"], "angle": turn})
