"""What a simulated participant does in one trial: rebuild the target scene the way a person would.

In ``basic``/``full`` it asks for suggestions at each target object's contact point on its parent (a click with
a small error) and picks the object's model at the rank the engine really gave it (searching by keyword when it
is absent); in ``none`` it scans the fixed model list or searches. It then drags and turns the object until its
pose matches the target. Every action costs time on the trial's :class:`~.timing.Clock` and is logged as the
browser would log it — scene changes with the states of the objects they changed (event vocabulary 2) — and
events are sent in batches, as the outbox does. "Done" submits the scene the bot built, which need not be the
target: a turn within the tolerance or one its symmetry makes invisible is left alone.
"""

from __future__ import annotations

import math
import re
import time

import numpy as np

from scenesuggest import poses
from scenesuggest.symmetry import glb_symmetry_period_deg, visible_turn_deg

from .timing import LIST_VISIBLE, SCAN_PER_ITEM, B, Clock, K, M, P, drag_seconds, turn_seconds
from .transport import FlowError

POSE_TOLERANCE_DEG, POSE_TOLERANCE_M = 4.0, 0.03
#: Where a click for a new object lands: the intended contact point plus a random error in the surface plane
#: (standard deviation, m), at most a tenth of the support's smaller side; the object is then dragged into place.
CLICK_ERROR_M = 0.15
BATCH = 200  # events per request, as the outbox sends them


def rotation_of(transform: list[float]) -> np.ndarray:
    """The 3×3 rotation of a column-major 4×4 rigid transform."""
    return np.asarray(transform, dtype=float).reshape(4, 4).T[:3, :3]


def canonical_pose(obj: dict) -> tuple[np.ndarray, np.ndarray]:
    """Where the list and search place an object at its click point: its attachment face on the surface, not
    turned (α = 0); returns the origin (metres, world) and the 3×3 rotation."""
    t = poses.placement(obj["click"], obj["contact_normal"], obj["attachment_face"], obj["size"], 0.0)
    return t[:3, 3], t[:3, :3]


def turned(transform: list[float], normal, degrees: float, position) -> list[float]:
    """A column-major transform turned by ``degrees`` about the unit ``normal`` and moved to ``position``."""
    m = np.eye(4)
    m[:3, :3] = poses.axis_rotations(normal, [math.radians(degrees)])[0] @ rotation_of(transform)
    m[:3, 3] = position
    return m.T.reshape(-1).tolist()


def _rounded(state: dict) -> dict:
    """An object state with its numbers to 0.1 µm, as the browser logs them (scene-model.js ``stateJSON``)."""
    return {k: [round(float(x), 7) for x in v] if k in ("size", "transform", "contact_point", "contact_normal")
            and v is not None else v for k, v in state.items()}


def words(category: str) -> str:
    """The search text a person would type for a category: ``DeskLamp`` → ``desk lamp``."""
    return re.sub(r"(?<=[a-z])(?=[A-Z])", " ", category).lower()


class Trial:
    """One trial of participant ``who`` (a :class:`~.participant.Bot`), from the trial page's boot data."""

    def __init__(self, who, boot: dict):
        self.who = who
        self.token, self.trial, self.page_id = boot["token"], boot["trial"], boot["page_id"]
        self.vocabulary = boot["vocabulary"]  # the event vocabulary's version the page logs in
        self.batch: list[dict] = []
        self.clock = Clock(who.rng, who.speed, time.time() * 1000.0)
        #: the scene as the bot has built it: object id → state (an object as a scene file lists it)
        self.objects: dict[str, dict] = {}

    def spend(self, seconds: float) -> None:
        self.clock.spend(seconds)

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
    def state(obj: dict, *, id: str, model_id: str, size, transform, face: str) -> dict:
        """The state of a placed object: ``obj`` (the target object being rebuilt, with its ``click``) placed
        as ``model_id`` of ``size`` with ``transform`` (column-major) on ``face``, at the click."""
        return {"id": id, "model_id": model_id, "category": obj["category"], "size": list(size),
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
            self.spend(M)  # find the next object in the target view
            if not self.place(obj, condition):
                who.result.missing_objects += 1
        self.spend(M + P + B + P + B)  # "done", then confirm
        self.event("trial_done", {"objects": len(self.objects) - len(present)})
        self.flush()
        self.api("POST", "/trial/done", {"trial": index, "scene": {"objects": self.scene_list()},
                                         "last_seq": self.who.seq - 1})
        return self.clock.elapsed

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
        for i in range(0, len(self.batch), BATCH):
            chunk = self.batch[i:i + BATCH]
            body = {"page_id": self.page_id, "vocabulary": self.vocabulary, "events": chunk}
            if self.who.chance(self.who.does.resend):
                self.api("POST", "/events", body)
            acked = self.api("POST", "/events", body)["acked_seq"]
            if acked != chunk[-1]["seq"]:
                raise FlowError(f"events up to {chunk[-1]['seq']} sent, {acked} acknowledged")
        self.who.result.events += len(self.batch)
        self.batch = []

    # -- finding a model --------------------------------------------------------------------------------------------
    def search(self, text: str) -> dict:
        self.spend(M + P + B + K * len(text))
        self.event("search", {"text": text})
        found = self.api("GET", f"/search?q={text.replace(' ', '+')}")
        self.event("list_shown", {"source": "search", "items": [h["id"] for h in found["hits"]],
                                  "list_id": found["list_id"]})
        return found

    def find_by_search(self, obj: dict) -> tuple[int, str] | None:
        """Search for the category's words, then for the model's name (what a person reads in the list)."""
        name = self.who.library.get(obj["model_id"], {}).get("name", "")
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
        parent = self.objects[obj["parent"]]
        linear = rotation_of(parent["transform"]) * np.asarray(parent["size"], dtype=float)  # columns: world edges
        extent = np.abs(linear).sum(axis=1)  # the parent's world box size along x, y, z
        side = min(float(np.abs(u) @ extent), float(np.abs(v) @ extent))
        du, dv = self.who.rng.normal(0.0, min(CLICK_ERROR_M, side / 10), 2)
        return (np.asarray(obj["contact_point"], dtype=float) + du * u + dv * v).tolist()

    def place(self, obj: dict, condition: str) -> bool:
        """Bring one target object into the scene; returns False when the bot could not find its model."""
        obj = {**obj, "click": self.click_point(obj)}
        placed = self.place_from_list(obj) if condition == "none" else self.place_from_suggestions(obj)
        if placed is None:
            return False
        self.adjust(obj)
        return True

    def place_from_list(self, obj: dict):
        who = self.who
        ids = [m["id"] for m in who.fixed]
        if obj["model_id"] in ids and ids.index(obj["model_id"]) < LIST_VISIBLE and not who.overlooks():
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
        self.change("insert", {"object": obj["id"], "model": obj["model_id"], "category": obj["category"],
                               "rank": rank, "source": source, "list_id": list_id}, [self.canonical_state(obj)])
        return obj["id"]

    def canonical_state(self, obj: dict) -> dict:
        """``obj``'s model where the list and search put it: at the click, in its canonical pose."""
        position, rotation = canonical_pose(obj)
        m = np.eye(4)
        m[:3, :3], m[:3, 3] = rotation, position
        return self.state(obj, id=obj["id"], model_id=obj["model_id"], size=obj["size"],
                          transform=m.T.reshape(-1), face=obj["attachment_face"])

    def place_from_suggestions(self, obj: dict):
        self.spend(P + K + B)  # shift-click the contact point
        body = {"trial": self.trial["index"], "scene": {"objects": self.scene_list()}, "parent": obj["parent"],
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
        self.change("insert", {"object": placed, "model": top["models"][0]["id"], "category": top["category"],
                               "rank": 1, "source": "context", "list_id": found["list_id"]},
                    [self.suggested_state({**obj, "category": top["category"]}, placed, top, top["models"][0])])
        for item in items:
            ids = [m["id"] for m in item["models"]]
            if obj["model_id"] in ids and not self.who.overlooks():
                rank = item["rank"]
                self.spend(SCAN_PER_ITEM * rank)
                if ids.index(obj["model_id"]) > 0:  # expand the category and pick the model
                    self.spend(P + B + SCAN_PER_ITEM * (ids.index(obj["model_id"]) + 1))
                # the condition's pose: oriented in full, canonical in basic
                chosen = self.suggested_state(obj, obj["id"], item, item["models"][ids.index(obj["model_id"])])
                if rank == 1 and ids.index(obj["model_id"]) == 0:
                    self._rename(placed, obj["id"])
                else:
                    self.spend(P + B)
                    self.change("replace", {"object": obj["id"], "replaces": placed, "model": obj["model_id"],
                                            "category": obj["category"], "rank": rank, "source": "context",
                                            "list_id": found["list_id"]}, [{"id": placed, "removed": True}, chosen])
                return obj["id"]
        self.spend(SCAN_PER_ITEM * len(items))
        searched = self.find_by_search(obj)
        if searched is None:
            self.spend(P + B)
            self.change("delete", {"object": placed}, [{"id": placed, "removed": True}])
            return None
        return self._chosen(obj, searched[0], "search", searched[1], placed)

    def suggested_state(self, obj: dict, id: str, item: dict, model: dict) -> dict:
        """``model`` of a suggestion ``item`` where the suggestion places it (the engine's pose in full, the
        canonical pose in basic, at the click)."""
        return self.state(obj, id=id, model_id=model["id"], size=model["size"], transform=item["placement"],
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

    def _chosen(self, obj, rank, source, list_id, replaces):
        kind = "replace" if replaces else "insert"
        payload = {"object": obj["id"], "model": obj["model_id"], "category": obj["category"], "rank": rank,
                   "source": source, "list_id": list_id}
        states = [self.canonical_state(obj)]
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
        """Drag the placed object to the target position, then turn it from its placed orientation to the
        target's about the support normal."""
        placed = self.objects[obj["id"]]
        target_position = obj["transform"][12:15]
        distance = float(np.linalg.norm(np.subtract(placed["transform"][12:15], target_position)))
        if distance > POSE_TOLERANCE_M:
            self.spend(M + P)
            self.event("move_start", {"object": obj["id"]})
            self.spend(drag_seconds(distance))
            moved = {**placed, "transform": placed["transform"][:12] + list(target_position) + [1.0],
                     "contact_point": list(obj["contact_point"])}
            self.change("move_end", {"object": obj["id"], "distance": distance, "parent": obj["parent"]}, [moved])
            placed = moved
        normal = obj["contact_normal"]
        turn = math.degrees(poses.turn_about(rotation_of(placed["transform"]), rotation_of(obj["transform"]),
                                             normal))
        if abs(normal[1]) > 0.9:  # on a floor or a table: only a visible difference is turned
            turn = visible_turn_deg(turn, self.period_of(placed["model_id"]))
        if abs(turn) > POSE_TOLERANCE_DEG:
            self.spend(M + P + B)  # select it and think about the turn
            self.event("rotate_start", {"object": obj["id"]})
            self.spend(turn_seconds(turn, POSE_TOLERANCE_DEG))
            after = {**placed, "transform": turned(placed["transform"], normal, turn, target_position)}
            self.change("rotate_end", {"object": obj["id"], "angle": turn}, [after])
