"""``ai2thor`` — the AI2-THOR rooms shipped as data in the PyPI package ``procthor``.

The file ``procthor/databases/ai2thor-object-metadata.json`` is read as package data; procthor's modules
are never imported. It holds 120 iTHOR rooms (30 each of bathroom, bedroom, kitchen, living room) and
75 RoboTHOR rooms, with each object's type, pose, boxes and ``parentReceptacles``.

Conversion: Unity is left-handed (+Z forward, metres, +Y up). Negating x gives our right-handed world
and keeps each object's front on +Z; a Unity yaw θ becomes −θ. Every object type becomes one model,
``ai2thor:<Type>``, whose canonical size is the type's median box; an instance's transform scales it
to the instance's own box. Room shells are synthesised: one ``Room`` root per scene, a box spanning the
floor and every object, whose floor and walls support the objects that rest on them.

Support: of the listed ``parentReceptacles``, the one whose top is closest to the child's bottom;
objects without one rest inside the smallest object that contains them (items in drawers), else on
an object just below them, else on the floor when their bottom is near it, else on the nearest wall.
Parents always sit lower than their children (``_Box.rank``), so the support tree has no cycles.
"""

from __future__ import annotations

import json
import math
from collections import defaultdict
from dataclasses import dataclass
from importlib import resources

import numpy as np

from ..errors import SceneSuggestError
from ..library.index import ModelInfo
from ..scenes import frames, surfaces
from ..scenes.scene import ROOM, ObjectInstance, Scene
from ..scenes.scene_types import infer_scene_type
from ..scenes.taxonomy import ai2thor_taxonomy
from .corpus import Corpus, Progress, no_progress

METADATA = "databases/ai2thor-object-metadata.json"
ROOM_TYPES = {"bathrooms": "Bathroom", "bedrooms": "Bedroom", "kitchens": "Kitchen",
              "living_rooms": "LivingRoom"}
ROOM_MODEL = "ai2thor:Room"
#: Objects without a support of their own rest on the floor when their bottom is this close to it
#: (kitchen drawers and cabinets float a few cm up), on an object whose top is this close below them,
#: inside an object that contains their box within this tolerance; otherwise on the nearest wall.
FLOOR_GAP_M = 0.15
REST_GAP_M = 0.05
CONTAIN_TOLERANCE_M = 0.02
MIN_ROOM_HEIGHT_M = 2.5
MIN_SIZE_M = 0.005
#: Types whose metadata box is only their work surface (a counter top is a 2 cm slab about 0.9 m up, with
#: nothing under it in the file): each stands for the solid counter beneath it, so its box is taken down to the
#: floor — it then stands on the floor, what is on it rests on its top, and it holds nothing inside.
FLOOR_STANDING = frozenset({"CounterTop"})


@dataclass
class _Box:
    """An object's pose and box in our world frame."""

    lo: np.ndarray  # axis-aligned world bbox
    hi: np.ndarray
    yaw: float  # radians about +Y
    size: np.ndarray  # oriented extent along the object's own axes (x, y, z)

    def __post_init__(self) -> None:
        # Support order: a parent must come strictly before its child (lower bottom, then larger volume).
        # Rounding the bottom to 1 cm makes this a strict order, so the support graph has no cycle.
        self.volume = float(np.prod(self.hi - self.lo))
        self.rank = (round(float(self.lo[1]), 2), -self.volume)

    @property
    def bottom_centre(self) -> np.ndarray:
        return np.array([(self.lo[0] + self.hi[0]) / 2, self.lo[1], (self.lo[2] + self.hi[2]) / 2])

    def down_to(self, floor: float) -> None:
        """Take the box's bottom down to ``floor`` (metres, world Y)."""
        self.lo[1] = floor
        self.size[1] = max(float(self.hi[1] - floor), MIN_SIZE_M)
        self.__post_init__()

    def contains(self, other: _Box, tol: float = CONTAIN_TOLERANCE_M) -> bool:
        return bool(np.all(other.lo >= self.lo - tol) and np.all(other.hi <= self.hi + tol))

    def covers(self, point: np.ndarray) -> bool:
        """Whether ``point`` lies over (or in) the box's footprint."""
        return bool(self.lo[0] - 0.01 <= point[0] <= self.hi[0] + 0.01
                    and self.lo[2] - 0.01 <= point[2] <= self.hi[2] + 0.01)


def read_rooms() -> dict[str, list[list[dict]]]:
    """The room groups of the installed procthor package data."""
    try:
        ref = resources.files("procthor").joinpath(METADATA)
        return json.loads(ref.read_text(encoding="utf-8"))
    except (ModuleNotFoundError, FileNotFoundError) as e:
        raise SceneSuggestError(f"the AI2-THOR rooms need the package procthor==0.0.1.dev2 ({e})",
                                file=METADATA) from None


def _box(o: dict) -> _Box:
    aabb = o["axisAlignedBoundingBox"]
    c, s = aabb["center"], aabb["size"]
    centre = np.array([-c["x"], c["y"], c["z"]])
    half = np.array([s["x"], s["y"], s["z"]]) / 2
    yaw = -math.radians(o["rotation"]["y"])
    size = np.array([s["x"], s["y"], s["z"]])
    oobb = o.get("objectOrientedBoundingBox")
    if oobb and oobb.get("cornerPoints"):
        pts = np.array(oobb["cornerPoints"], dtype=float) * [-1, 1, 1]
        r = frames.rotation_y(yaw)[:3, :3]
        local = pts @ r  # into the object's axes
        size = local.max(axis=0) - local.min(axis=0)
    elif abs(math.sin(yaw)) > math.sqrt(0.5):
        size = size[[2, 1, 0]]
    return _Box(centre - half, centre + half, yaw, np.maximum(size, MIN_SIZE_M))


def load_ai2thor(progress: Progress = no_progress) -> Corpus:
    """Load every AI2-THOR room; scene ids are ``<group>-NN`` (``kitchens-07``, ``robothor-12``)."""
    groups = read_rooms()
    taxonomy = ai2thor_taxonomy()
    rooms = [_Room(f"{g}-{i:02d}", ROOM_TYPES.get(g), objs) for g, rs in groups.items() for i, objs in enumerate(rs)]
    sizes = defaultdict(list)
    for room in progress(rooms, "finding supports"):
        room.find_supports()
        for o in room.objects:
            sizes[o["objectType"]].append(room.boxes[o["objectId"]].size)
    type_size = {t: np.median(np.array(v), axis=0) for t, v in sizes.items()}
    models = {f"ai2thor:{t}": _model_info(t, s, taxonomy) for t, s in type_size.items()}
    models[ROOM_MODEL] = _model_info(ROOM, np.ones(3), taxonomy)
    scenes = [room.scene(type_size, taxonomy) for room in rooms]
    return Corpus("ai2thor", scenes, models, taxonomy)


def _model_info(object_type: str, size: np.ndarray, taxonomy) -> ModelInfo:
    half = size / 2
    return ModelInfo(
        id=f"ai2thor:{object_type}" if object_type != ROOM else ROOM_MODEL,
        category=object_type, category_path=taxonomy.path(object_type),
        name=_words(object_type), tags=[w.lower() for w in _words(object_type).split()],
        description=" ".join(_words(c) for c in taxonomy.path(object_type)),
        raw_bbox=((-half[0], 0.0, -half[2]), (half[0], size[1], half[2])),
        size_source="procedural",
    )


def _words(name: str) -> str:
    """``"TVStand"`` → ``"TV Stand"``, ``"ArmChair"`` → ``"Arm Chair"``."""
    out = ""
    for i, ch in enumerate(name):
        if i and ch.isupper() and (not name[i - 1].isupper() or (i + 1 < len(name) and name[i + 1].islower())):
            out += " "
        out += ch
    return out


def _room_box(room: list[dict], boxes: dict[str, _Box]) -> tuple[np.ndarray, np.ndarray]:
    floors = [boxes[o["objectId"]] for o in room if o["objectType"] == "Floor"]
    others = [boxes[o["objectId"]] for o in room if o["objectType"] != "Floor"]
    if not others:
        raise SceneSuggestError("room has no objects", file=METADATA)
    lo = np.min([b.lo for b in others], axis=0)
    hi = np.max([b.hi for b in others], axis=0)
    if floors:
        lo[1] = floors[0].hi[1]
        lo[[0, 2]] = np.maximum(lo[[0, 2]], floors[0].lo[[0, 2]])
        hi[[0, 2]] = np.minimum(hi[[0, 2]], floors[0].hi[[0, 2]])
    hi[1] = max(hi[1] + 0.05, lo[1] + MIN_ROOM_HEIGHT_M)
    return lo, hi


def _support(o: dict, boxes: dict[str, _Box], others: list[str], room_lo: np.ndarray, room_hi: np.ndarray,
             floor_ids: set[str], solid: frozenset[str] = frozenset()) -> tuple[str | None, np.ndarray, np.ndarray]:
    """(parent object id or None for the room, contact point, contact normal) of one object; ``solid`` objects
    hold nothing inside."""
    box = boxes[o["objectId"]]
    bottom = box.bottom_centre
    up = np.array([0.0, 1.0, 0.0])
    below = [p for p in others if p != o["objectId"] and boxes[p].rank < box.rank]
    listed = o.get("parentReceptacles") or []
    candidates = [p for p in listed if p in below]
    if candidates:
        best = min(candidates, key=lambda p: (not boxes[p].covers(bottom), abs(boxes[p].hi[1] - bottom[1])))
        return best, bottom, up
    on_floor = np.array([bottom[0], room_lo[1], bottom[2]])
    near_floor = bottom[1] - room_lo[1] <= FLOOR_GAP_M
    listed_on_floor = any(p in floor_ids for p in listed)
    if listed_on_floor and near_floor:
        return None, on_floor, up
    containers = [p for p in below if p not in solid and boxes[p].contains(box)]
    if containers:
        return min(containers, key=lambda p: boxes[p].volume), bottom, up
    resting_on = [p for p in below if boxes[p].covers(bottom)
                  and -CONTAIN_TOLERANCE_M <= bottom[1] - boxes[p].hi[1] <= REST_GAP_M]
    if resting_on:
        return max(resting_on, key=lambda p: boxes[p].hi[1]), bottom, up
    if listed_on_floor or near_floor:
        return None, on_floor, up
    return (None, *_wall_contact(box, room_lo, room_hi))


def _wall_contact(box: _Box, room_lo: np.ndarray, room_hi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Contact with the nearest wall of the room box: the centre of the object's box side facing it."""
    centre = (box.lo + box.hi) / 2
    walls = [  # (distance from the box side to the wall, axis, sign of the inward wall normal)
        (box.lo[0] - room_lo[0], 0, 1.0), (room_hi[0] - box.hi[0], 0, -1.0),
        (box.lo[2] - room_lo[2], 2, 1.0), (room_hi[2] - box.hi[2], 2, -1.0),
    ]
    _, axis, sign = min(walls, key=lambda w: abs(w[0]))
    point = centre.copy()
    point[axis] = box.lo[axis] if sign > 0 else box.hi[axis]
    normal = np.zeros(3)
    normal[axis] = sign
    return point, normal


class _Room:
    """One room of the metadata file on its way to a :class:`Scene`."""

    def __init__(self, scene_id: str, scene_type: str | None, objects: list[dict]):
        self.scene_id = scene_id
        self.scene_type = scene_type
        self.floor_ids = {o["objectId"] for o in objects if o["objectType"] == "Floor"}
        self.ids = {o["objectId"]: str(i) for i, o in enumerate(objects)}  # position in the file
        self.objects = [o for o in objects if o["objectType"] != "Floor"]
        self.boxes = {o["objectId"]: _box(o) for o in objects}
        self.lo, self.hi = _room_box(objects, self.boxes)
        self.solid = frozenset(o["objectId"] for o in self.objects if o["objectType"] in FLOOR_STANDING)
        for object_id in self.solid:
            self.boxes[object_id].down_to(float(self.lo[1]))
        self.supports: dict[str, tuple[str | None, np.ndarray, np.ndarray]] = {}

    def find_supports(self) -> None:
        """Each object's support; objects on walls are turned to face out of the wall (AI2-THOR's own
        yaw of wall art and fixtures often points into the wall or comes from a lying-down asset)."""
        others = [o["objectId"] for o in self.objects]
        for o in self.objects:
            support = _support(o, self.boxes, others, self.lo, self.hi, self.floor_ids, self.solid)
            self.supports[o["objectId"]] = support
            normal = support[2]
            if abs(normal[1]) < 0.5:
                box = self.boxes[o["objectId"]]
                extent = box.hi - box.lo
                along = extent[2] if abs(normal[0]) > 0.5 else extent[0]
                depth = extent[0] if abs(normal[0]) > 0.5 else extent[2]
                box.yaw = math.atan2(normal[0], normal[2])
                box.size = np.maximum(np.array([along, extent[1], depth]), MIN_SIZE_M)

    def scene(self, type_size: dict[str, np.ndarray], taxonomy) -> Scene:
        room_t = (frames.translation([(self.lo[0] + self.hi[0]) / 2, self.lo[1], (self.lo[2] + self.hi[2]) / 2])
                  @ frames.scaling(self.hi - self.lo))
        scene = Scene(self.scene_id, self.scene_type or ROOM, source=f"ai2thor:{self.scene_id}")
        scene.objects["room"] = ObjectInstance("room", ROOM_MODEL, ROOM, room_t, (1.0, 1.0, 1.0))
        ids = self.ids
        for o in self.objects:
            box, model_size = self.boxes[o["objectId"]], type_size[o["objectType"]]
            t = (frames.translation(box.bottom_centre) @ frames.rotation_y(box.yaw)
                 @ frames.scaling(box.size / np.maximum(model_size, MIN_SIZE_M)))
            scene.objects[ids[o["objectId"]]] = ObjectInstance(
                ids[o["objectId"]], f"ai2thor:{o['objectType']}", o["objectType"], t,
                tuple(float(v) for v in model_size))
        for o in self.objects:
            inst = scene.objects[ids[o["objectId"]]]
            parent, point, normal = self.supports[o["objectId"]]
            inst.parent = ids[parent] if parent else "room"
            inst.contact_point = tuple(float(v) for v in point)
            inst.contact_normal = tuple(float(v) for v in normal)
            parent_inst = scene.objects[inst.parent]
            inst.surface_type = surfaces.surface_type(parent_inst.transform, parent_inst.size, point, normal)
            inst.attachment_face = surfaces.attachment_face(inst.transform, normal)
        scene.validate(file=f"{METADATA}#{self.scene_id}")
        if self.scene_type is None:
            scene.scene_type = infer_scene_type((o.category for o in scene), taxonomy)
            scene.type_from_objects = True
        return scene
