"""What a simulated participant does in one trial: rebuild the target scene the way a person would.

Before each object the person looks round the scene (camera orbits) and hesitates before every action. In
``none`` they scan the fixed model list, item by item, up to their patience (or type a search first); in
``basic``/``full`` they ask for suggestions at the object's contact point on its parent (a click with a small
error, on the parent) and look through the ranked categories as the engine really gave them. When the wanted
model is not where they look, they search with words they would use — the category's words or the model's name
and tags, reformulated with the category's parents in the taxonomy when the results do not show it — and
choose the wanted model when they see it, else a model of its category of similar size. They then drag the
object towards the target position (each drag misses by a little and is corrected) and turn it (going past and
coming back). Every behaviour's parameter is in :class:`~.human.Human`; operator times in :mod:`.timing`.

Every action costs time on the trial's :class:`~.timing.Clock` and is logged as the browser would log it —
scene changes with the states of the objects they changed (event vocabulary 2) — and events are sent in
batches, as the outbox does. "Done" submits the scene the bot built, which need not be the target.
"""

from __future__ import annotations

import math
import re
import time

import numpy as np

from scenesuggest.assets.symmetry import glb_symmetry_period_deg, visible_turn_deg
from scenesuggest.scenes import frames, poses

from .timing import B, Clock, K, M, P, drag_seconds, turn_seconds
from .transport import FlowError

#: Where a click for a new object lands: the intended contact point plus a random error in the surface plane
#: (standard deviation, m), at most a tenth of the support's smaller side; the object is then dragged into place.
CLICK_ERROR_M = 0.15
MAX_DRAGS = 6  # corrections a person makes before leaving an object where it is
ORBIT_S = 2.0  # seconds of looking round per logged camera orbit


def canonical_pose(obj: dict) -> tuple[np.ndarray, np.ndarray]:
    """Where the list and search place an object at its click point: its attachment face on the surface, not
    turned (α = 0); returns the origin (metres, world) and the 3×3 rotation."""
    t = poses.placement(obj["click"], obj["contact_normal"], obj["attachment_face"], obj["size"], 0.0)
    return t[:3, 3], t[:3, :3]


def turned(transform: list[float], normal, degrees: float, position) -> list[float]:
    """A column-major transform turned by ``degrees`` about the unit ``normal`` and moved to ``position``."""
    m = np.eye(4)
    m[:3, :3] = poses.axis_rotations(normal, [math.radians(degrees)])[0] @ frames.from_column_major(transform)[:3, :3]
    m[:3, 3] = position
    return m.T.reshape(-1).tolist()


def _rounded(state: dict) -> dict:
    """An object state with its numbers to 0.1 µm, as the browser logs them (scene-model.js ``stateJSON``)."""
    return {k: [round(float(x), 7) for x in v] if k in ("size", "transform", "contact_point", "contact_normal")
            and v is not None else v for k, v in state.items()}


def words(category: str) -> str:
    """The search text a person would type for a category: ``DeskLamp`` → ``desk lamp``."""
    return re.sub(r"(?<=[a-z])(?=[A-Z])", " ", category).lower()


def search_words(text: str) -> list[str]:
    """The words of a model's name or tag a person might type: letters only, three or more, lower case."""
    return re.findall(r"[a-z]{3,}", words(text))


def misspelt(text: str, u: float) -> str:
    """``text`` as a person mistypes it: two neighbouring letters of its longest word swapped, after the first
    (people get that one right), where ``u`` (in [0, 1)) says (``desk lamp`` → ``dsek lamp``); a doubled letter is
    typed once instead. Mostly a word the library's names and tags do not hold."""
    longest = max(text.split(), key=len)
    if len(longest) < 3:
        return text + longest[-1]
    at = 1 + int(u * (len(longest) - 2))  # swap letters at and at + 1
    typed = longest[:at] + longest[at + 1] + longest[at] + longest[at + 2:]
    if typed == longest:
        typed = longest[:at] + longest[at + 1:]
    return text.replace(longest, typed, 1)


def box_of(state: dict) -> tuple[np.ndarray, np.ndarray]:
    """The world axis-aligned box (low, high corners, metres) of an object state."""
    return frames.world_bbox(np.asarray(state["transform"], dtype=float).reshape(4, 4).T, state["size"])


class BotTrial:
    """One trial of participant ``who`` (a :class:`~.participant.Bot`), from the trial page's boot data."""

    def __init__(self, who, boot: dict):
        self.who, self.human = who, who.human
        self.token, self.trial, self.page_id = boot["token"], boot["trial"], boot["page_id"]
        self.vocabulary = boot["vocabulary"]  # the event vocabulary's version the page logs in
        self.per_request = boot["batch"]  # events per request, as the page's outbox sends them
        self.batch: list[dict] = []
        factor = who.speed * who.scene_factor(self.trial["scene"]) * self.human.practice_factor(who.played)
        self.clock = Clock(who.rng, factor, time.time() * 1000.0)
        #: the scene as the bot has built it: object id → state (an object as a scene file lists it)
        self.objects: dict[str, dict] = {}
        self.overlooked: set[str] = set()  # target objects whose model this person has once missed in a list

    def spend(self, seconds: float) -> None:
        self.clock.spend(seconds)

    def act(self, seconds: float) -> None:
        """An action of ``seconds`` operator time, after a hesitation (exponential, mean ``hesitation_s``)."""
        self.spend(self.who.rng.exponential(1.0) * self.human.hesitation_s + seconds)

    def event(self, kind: str, payload: dict) -> None:
        self.batch.append({"seq": self.who.seq, "t": self.clock.ms, "type": kind, "trial": self.trial["index"],
                           "payload": payload})
        self.who.seq += 1

    def change(self, kind: str, payload: dict, states: list[dict]) -> None:
        """Apply ``states`` (objects as a scene file lists them, or ``{"id", "removed": True}``) to the scene and
        log the event that made them, carrying them."""
        states = [s if s.get("removed") else _rounded(s) for s in states]
        for s in states:
            if s.get("removed"):
                self.objects.pop(s["id"], None)
            else:
                self.objects[s["id"]] = s
        self.event(kind, {**payload, "objects": [dict(s) for s in states]})

    @staticmethod
    def state(obj: dict, *, id: str, model: dict, transform, face: str) -> dict:
        """The state of a placed object: ``obj`` (the target object being rebuilt, with its ``click``) placed
        as ``model`` (a library entry: id, category, size) with ``transform`` (column-major) on ``face``."""
        return {"id": id, "model_id": model["id"], "category": model["category"], "size": list(model["size"]),
                "transform": [float(v) for v in transform], "parent": obj["parent"],
                "surface_type": obj.get("surface_type"), "attachment_face": face, "contact_point": obj["click"],
                "contact_normal": list(obj["contact_normal"])}

    def scene_list(self) -> list[dict]:
        return list(self.objects.values())

    def api(self, method: str, path: str, body=None) -> dict:
        headers = {"Authorization": f"Bearer {self.token}"}
        http = self.who.http
        r = (http.get(f"/api{path}", headers=headers) if method == "GET" else
             http.post(f"/api{path}", json_body=body, headers=headers))
        if r.status >= 400:
            raise FlowError(f"{method} /api{path} → {r.status}: {r.text[:200]}")
        return r.json()

    # -- the trial ------------------------------------------------------------------------------------------------
    def play(self) -> float:
        """Rebuild the target, press "done"; returns the simulated seconds the trial took."""
        who, index, condition = self.who, self.trial["index"], self.trial["condition"]
        target = self.api("GET", f"/scenes/{self.trial['scene']}?which=target")
        start = self.api("GET", f"/scenes/{self.trial['scene']}?which=start")
        present = {o["id"] for o in start["objects"]}
        self.objects = {o["id"]: dict(o) for o in start["objects"]}
        self.event("trial_start", {"scene": self.trial["scene"], "condition": condition})
        if not who.library:  # the study's models, once per session
            who.fixed = self.api("GET", "/models")["models"]
            who.library = {m["id"]: m for m in who.fixed}
        todo = [o for o in target["objects"] if o["id"] not in present]
        reopen_at = len(todo) // 2 if (who.chance(who.does.reload) or who.chance(who.does.second_tab)) else None
        for k, obj in enumerate(todo):
            if k == reopen_at:
                self.reopen()
            if obj["parent"] not in self.objects:  # its support could not be found: nothing to stand it on
                who.result.missing_objects += 1
                continue
            self.look_round()
            self.act(M)  # find the next object in the target view
            if not self.place(obj, condition):
                who.result.missing_objects += 1
        self.act(M + P + B + P + B)  # "done", then confirm
        self.event("trial_done", {"objects": len(self.objects) - len(present)})
        self.flush()
        self.api("POST", "/trial/done", {"trial": index, "scene": {"objects": self.scene_list()},
                                         "last_seq": self.who.seq - 1})
        return self.clock.elapsed

    def look_round(self) -> None:
        """Look round the scene before the next object (exponential, mean ``look_round_s``), logged as the
        camera orbits the browser logs (one per ORBIT_S seconds begun)."""
        seconds = self.who.rng.exponential(1.0) * self.human.look_round_s
        distance = 2.5 * float(self.who.rng.lognormal(0.0, 0.2))
        for _ in range(math.ceil(seconds / ORBIT_S)):
            self.spend(min(seconds, ORBIT_S))
            seconds -= ORBIT_S
            self.event("camera", {"action": "orbit", "distance": round(distance, 3)})

    def reopen(self) -> None:
        """The page is loaded again (reload or a second tab): what was logged is sent, the trial resumes."""
        self.flush()
        boot = self.who.walker.current().boot
        if boot is None or boot["trial"]["index"] != self.trial["index"]:
            raise FlowError("the reopened page did not resume the trial")
        self.page_id = boot["page_id"]
        self.who.result.reloads += 1
        self.event("resume", {"reason": "reload"})

    def flush(self) -> None:
        for i in range(0, len(self.batch), self.per_request):
            chunk = self.batch[i:i + self.per_request]
            body = {"page_id": self.page_id, "vocabulary": self.vocabulary, "events": chunk}
            if self.who.chance(self.who.does.resend):
                self.api("POST", "/events", body)
            acked = self.api("POST", "/events", body)["acked_seq"]
            if acked != chunk[-1]["seq"]:
                raise FlowError(f"events up to {chunk[-1]['seq']} sent, {acked} acknowledged")
        self.who.result.events += len(self.batch)
        self.batch = []

    # -- finding a model --------------------------------------------------------------------------------------------
    def look_through(self, obj: dict, models: list[dict], patience: float,
                     substitute: bool = True) -> tuple[int, dict] | None:
        """Look at the first ``patience`` of ``models`` one by one: the wanted model when seen (unless
        overlooked: once per object), else — having looked at them all, and if ``substitute`` — another model of
        the wanted category, of the most similar size. Returns (1-based rank, model) or None, having spent the
        scanning time."""
        seen = models[:max(1, round(patience))]
        wanted = obj["model_id"]
        for rank, model in enumerate(seen, start=1):
            if model["id"] == wanted:
                if obj["id"] in self.overlooked or not self.who.overlooks():
                    self.spend(self.human.scan_item_s * rank)
                    return rank, model
                self.overlooked.add(obj["id"])  # missed once; looked at more carefully from now on
        self.spend(self.human.scan_item_s * len(seen))
        same = [(r, m) for r, m in enumerate(seen, start=1) if m["category"] == obj["category"] and m["id"] != wanted]
        if not same or not substitute:
            return None
        size = np.log(np.maximum(obj["size"], 1e-3))
        return min(same, key=lambda rm: float(np.abs(np.log(np.maximum(rm[1]["size"], 1e-3)) - size).sum()))

    def search_texts(self, obj: dict) -> list[str]:
        """What this person types for ``obj``, in order: the category's words or words of the model's name and
        tags (which first: ``category_words``), then the other, then the category's parents in the taxonomy
        (most specific first); at most 1 + ``reformulations`` different texts. With chance ``generic_words``
        the category's words are first cut to their last (the head noun: ``desk lamp`` → ``lamp``), which
        matches more models; with chance ``tag_words`` the person's own words are one of the model's tags (what it
        is for or looks like), which other models share; with chance ``unknown_words`` the first text is
        mistyped and finds nothing useful."""
        model = self.who.library.get(obj["model_id"], {})
        category = words(obj["category"])
        own = list(dict.fromkeys(search_words(model.get("name", "")) + [w for tag in model.get("tags", ())
                                                                        for w in search_words(tag)]))
        # drawn always: common random numbers
        two, category_first, generic, tag, unknown, typo = self.who.rng.random(6)
        named = list(dict.fromkeys(search_words(model.get("name", ""))))
        tagged = list(dict.fromkeys(w for t in model.get("tags", ()) for w in search_words(t)))
        if tag < self.human.tag_words and tagged:
            own_text = tagged[int(two * len(tagged))]  # one word of what it is for or looks like
        else:
            own = list(dict.fromkeys(named + tagged))
            own_text = (" ".join(own[:2]) if two < 0.5 else own[0]) if own else category
        said = [category.split()[-1], category] if generic < self.human.generic_words else [category]
        first = [*said, own_text] if category_first < self.human.category_words else [own_text, *said]
        parents = [words(c) for c in reversed(model.get("category_path", ())[:-1])]
        texts = list(dict.fromkeys(t for t in [*first, *parents, category.split()[-1]] if t))
        if unknown < self.human.unknown_words:
            texts.insert(0, misspelt(texts[0], typo))
        return texts[:1 + round(self.human.reformulations)]

    def search(self, text: str) -> dict:
        self.act(M + P + B + K * len(text))
        self.event("search", {"text": text})
        found = self.api("GET", f"/search?q={text.replace(' ', '+')}")
        self.event("list_shown", {"source": "search", "items": [h["id"] for h in found["hits"]],
                                  "list_id": found["list_id"]})
        return found

    def find_by_search(self, obj: dict) -> tuple[int, str, dict] | None:
        """Search with this person's words until the results show the wanted model (or one of its category);
        returns (rank, list id, model) or None when every text failed."""
        for text in self.search_texts(obj):
            found = self.search(text)
            chosen = self.look_through(obj, found["hits"], self.human.results_scanned)
            if chosen is not None:
                self.act(P + B)  # pick it
                return chosen[0], found["list_id"], chosen[1]
        return None

    def on_parent(self, obj: dict, point) -> list[float]:
        """``point`` kept on ``obj``'s parent: clamped into the parent's world box (as a click or a drag that
        stays on the surface it started on)."""
        low, high = box_of(self.objects[obj["parent"]])
        return np.clip(np.asarray(point, dtype=float), low, high).tolist()

    def plane_offset(self, obj: dict, sd: float) -> np.ndarray:
        """A random offset (metres) in the plane of ``obj``'s support surface, ``sd`` per direction."""
        n = np.asarray(obj["contact_normal"], dtype=float)
        n /= np.linalg.norm(n)
        u = np.cross(n, [0.0, 1.0, 0.0] if abs(n[1]) < 0.9 else [1.0, 0.0, 0.0])
        u /= np.linalg.norm(u)
        v = np.cross(n, u)
        du, dv = self.who.rng.normal(0.0, 1.0, 2) * sd
        return du * u + dv * v

    def click_point(self, obj: dict) -> list[float]:
        """Where the click that places ``obj`` lands: near its contact point, on its parent."""
        low, high = box_of(self.objects[obj["parent"]])
        side = float(np.sort(high - low)[1])  # the support's smaller side (of the two largest extents)
        offset = self.plane_offset(obj, min(CLICK_ERROR_M, side / 10))
        return self.on_parent(obj, np.asarray(obj["contact_point"], dtype=float) + offset)

    def place(self, obj: dict, condition: str) -> bool:
        """Bring one target object into the scene; returns False when the bot could not find its model."""
        obj = {**obj, "click": self.click_point(obj)}
        placed = self.place_from_list(obj) if condition == "none" else self.place_from_suggestions(obj)
        if placed is None:
            return False
        self.adjust(obj)
        return True

    def place_from_list(self, obj: dict):
        """``none``: scan the fixed list (or search first, ``search_first``), then click where it goes."""
        who = self.who
        found = None
        if who.rng.random() < self.human.search_first:
            found = self.find_by_search(obj)
        if found is None:
            chosen = self.look_through(obj, who.fixed, self.human.list_patience)
            if chosen is not None:
                self.act(P + B)
                found = (chosen[0], None, chosen[1])
            else:
                found = self.find_by_search(obj)
        if found is None:
            return None
        rank, list_id, model = found
        self.act(P + B)  # click the surface where it goes
        self.change("insert", {"object": obj["id"], "model": model["id"], "category": model["category"],
                               "rank": rank, "source": "fixed" if list_id is None else "search",
                               "list_id": list_id}, [self.canonical_state(obj, model)])
        return obj["id"]

    def canonical_state(self, obj: dict, model: dict) -> dict:
        """``model`` where the list and search put it: at the click, in its canonical pose."""
        position, rotation = canonical_pose({**obj, "size": model["size"]})
        m = np.eye(4)
        m[:3, :3], m[:3, 3] = rotation, position
        return self.state(obj, id=obj["id"], model=model, transform=m.T.reshape(-1), face=obj["attachment_face"])

    def place_from_suggestions(self, obj: dict):
        """``basic``/``full``: ask at the click; the top suggestion is placed; look through the ranked
        categories (``suggestion_patience``) and their models, else search."""
        self.act(P + K + B)  # shift-click the contact point
        body = {"trial": self.trial["index"], "scene": {"objects": self.scene_list()}, "parent": obj["parent"],
                "point": obj["click"], "normal": obj["contact_normal"]}
        self.event("context_query", {"parent": obj["parent"], "point": obj["click"],
                                     "normal": obj["contact_normal"]})
        found = self.api("POST", "/suggest", body)
        items = found["suggestions"]
        self.event("list_shown", {"source": "context", "items": [i["category"] for i in items],
                                  "list_id": found["list_id"]})
        if not items:
            searched = self.find_by_search(obj)
            return None if searched is None else self._chosen(obj, *searched, None)
        top = items[0]
        placed = f"{obj['id']}~s"
        self.change("insert", {"object": placed, "model": top["models"][0]["id"], "category": top["category"],
                               "rank": 1, "source": "context", "list_id": found["list_id"]},
                    [self.suggested_state(obj, placed, top, top["models"][0])])
        tiles = [{"id": i["category"], "category": i["category"], "size": i["models"][0]["size"]} for i in items]
        seen = self.look_through({**obj, "model_id": obj["category"]}, tiles, self.human.suggestion_patience,
                                 substitute=False)
        if seen is not None:
            item = items[seen[0] - 1]
            models = [{**m, "category": item["category"]} for m in item["models"]]
            at = next((k for k, m in enumerate(models) if m["id"] == obj["model_id"]), None)
            if at is None or at > 0:  # expand the category and look at its models
                self.act(P + B)
                model = self.look_through(obj, models, len(models))
                at = model[0] - 1 if model is not None else 0
            chosen = self.suggested_state(obj, obj["id"], item, models[at])
            if item["rank"] == 1 and at == 0:
                self._rename(placed, obj["id"])
            else:
                self.act(P + B)
                self.change("replace", {"object": obj["id"], "replaces": placed, "model": models[at]["id"],
                                        "category": obj["category"], "rank": item["rank"], "source": "context",
                                        "list_id": found["list_id"]}, [{"id": placed, "removed": True}, chosen])
            return obj["id"]
        searched = self.find_by_search(obj)
        if searched is None:
            self.act(P + B)
            self.change("delete", {"object": placed}, [{"id": placed, "removed": True}])
            return None
        return self._chosen(obj, *searched, placed)

    def suggested_state(self, obj: dict, id: str, item: dict, model: dict) -> dict:
        """``model`` of a suggestion ``item`` where the suggestion places it (the engine's pose in full, the
        canonical pose in basic, at the click)."""
        return self.state(obj, id=id, model={**model, "category": item["category"]}, transform=item["placement"],
                          face=item["attachment_face"])

    def _rename(self, placed: str, final: str) -> None:
        """The placed top suggestion was the one wanted: it was logged under its final id all along."""
        for e in self.batch:
            if e["payload"].get("object") == placed:
                e["payload"]["object"] = final
            for s in e["payload"].get("objects", ()):
                if s["id"] == placed:
                    s["id"] = final
        self.objects[final] = {**self.objects.pop(placed), "id": final}

    def _chosen(self, obj, rank, list_id, model, replaces):
        kind = "replace" if replaces else "insert"
        payload = {"object": obj["id"], "model": model["id"], "category": model["category"], "rank": rank,
                   "source": "search", "list_id": list_id}
        states = [self.canonical_state(obj, model)]
        if replaces:
            payload["replaces"] = replaces
            states.insert(0, {"id": replaces, "removed": True})
        self.change(kind, payload, states)
        return obj["id"]

    # -- getting the pose right ---------------------------------------------------------------------------------------
    def period_of(self, model_id: str) -> float:
        """How far the model can be turned before it looks different (from its mesh, as the browser shows it)."""
        symmetry = self.who.symmetry
        if model_id not in symmetry:
            model = self.who.library.get(model_id)
            r = self.who.http.get(model["asset"]) if model else None
            symmetry[model_id] = glb_symmetry_period_deg(r.body) if r is not None and r.status == 200 else 360.0
        return symmetry[model_id]

    def adjust(self, obj: dict) -> None:
        """Drag the placed object towards the target position until it is within ``position_tolerance_m`` (each
        drag ends off by ``drag_error`` of its distance, on the parent), then turn it towards the target's
        heading about the support normal (each turn ends off by ``turn_overshoot_deg`` per 90°, then is turned
        back) until within ``turn_tolerance_deg``; a person gives up after MAX_DRAGS tries of each."""
        h = self.human
        contact = np.asarray(obj["contact_point"], dtype=float)
        origin_offset = np.subtract(obj["transform"][12:15], contact)  # target origin relative to its contact
        for _ in range(MAX_DRAGS):
            placed = self.objects[obj["id"]]
            here = np.asarray(placed["contact_point"], dtype=float)
            distance = float(np.linalg.norm(here - contact))
            if distance <= h.position_tolerance_m:
                break
            self.act(M + P)
            self.event("move_start", {"object": obj["id"]})
            held = drag_seconds(distance) + self.who.rng.exponential(1.0) * h.drag_settle_s  # moving, then watching
            self.spend(held * self.who.drag_factor)
            end = self.on_parent(obj, contact + self.plane_offset(obj, h.drag_error * distance / math.sqrt(2)))
            if np.linalg.norm(np.subtract(end, contact)) <= h.position_tolerance_m:
                end = contact.tolist()
            position = (np.asarray(end) + origin_offset).tolist()
            moved = {**placed, "transform": placed["transform"][:12] + position + [1.0], "contact_point": end}
            self.change("move_end", {"object": obj["id"], "distance": float(np.linalg.norm(np.subtract(end, here))),
                                     "parent": obj["parent"]}, [moved])
        normal = obj["contact_normal"]
        for _ in range(MAX_DRAGS):
            placed = self.objects[obj["id"]]
            turn = math.degrees(poses.turn_about(frames.from_column_major(placed["transform"])[:3, :3],
                                                 frames.from_column_major(obj["transform"])[:3, :3],
                                                 normal))
            if abs(normal[1]) > 0.9:  # on a floor or a table: only a visible difference is turned
                turn = visible_turn_deg(turn, self.period_of(placed["model_id"]))
            if abs(turn) <= h.turn_tolerance_deg:
                break
            self.act(M + P + B)  # select it and think about the turn
            self.event("rotate_start", {"object": obj["id"]})
            miss = self.who.rng.normal(0.0, 1.0) * h.turn_overshoot_deg * abs(turn) / 90.0
            done = turn + miss if abs(miss) > h.turn_tolerance_deg else turn
            self.spend(turn_seconds(done, h.turn_tolerance_deg) + self.who.rng.exponential(1.0) * h.turn_settle_s)
            after = {**placed, "transform": turned(placed["transform"], normal, done, placed["transform"][12:15])}
            self.change("rotate_end", {"object": obj["id"], "angle": done}, [after])
