"""The context the paper's factors ignore, as counts over a corpus and as features of a click.

Where a click lies (:func:`describe_click`; metres, world frame, +Y up): its ``height`` above the floor (the
lowest point of the scene's roots), how near the parent's edge it is (``edge``: 0 at the centre of the clicked
face, 1 at its rim, in the parent's own frame), the distance to the nearest wall it stands in front of
(``wall``; NO_WALL_M when none), the log area of the clicked face of the parent's box (``area``, m²; a room's
floor: its footprint) and the free space around it (``free``: the distance to the nearest other object on the same
parent, NO_SIBLING_M when none).

What the corpus says of each candidate category (:class:`ContextStats`, counted over supported instances):
histograms of the five descriptors of its instances' contact points; in how many scenes it occurs, alone and
together with each other category; how many parent instances carry it, alone and together with each other
category; and how often it stands within NEAR_M of each other category. :meth:`ContextStats.features` turns
them into one row per candidate for a click: the log-likelihood of each descriptor under the candidate's
histogram (shrunk towards all categories'), the log-probability of the candidate given each category already
in the scene, on the parent and near the point (best and mean over them), its frequency overall and in the scene
type, and how many of it the scene and the parent already hold.
"""

from __future__ import annotations

import math

import numpy as np

from ...scenes import frames
from ...scenes.scene import ROOM, Scene
from ...scenes.walls import nearest_wall, room_walls

#: Bin edges of the descriptors (metres; ``area`` in log m²).
EDGES = {
    "height": np.array([0.02, 0.15, 0.35, 0.55, 0.7, 0.85, 1.0, 1.2, 1.5, 1.9]),
    "edge": np.array([0.2, 0.4, 0.6, 0.8, 0.95]),
    "wall": np.array([0.1, 0.25, 0.5, 1.0, 2.0]),
    "area": np.log([0.05, 0.15, 0.3, 0.6, 1.2, 3.0, 8.0]),
    "free": np.array([0.05, 0.1, 0.2, 0.4, 0.8, 1.5]),
}
DESCRIPTORS = tuple(EDGES)
NO_WALL_M = 5.0
NO_SIBLING_M = 3.0
#: Categories whose boxes come this close to a click (metres) are "near" it.
NEAR_M = 0.75
#: Pseudo-counts: of a descriptor histogram (towards all categories'), of co-occurrence (towards the base rate).
HIST_PRIOR = 2.0
COUNT_PRIOR = 0.5
#: Where a category has nothing to be conditioned on (an empty parent, nothing near): this log-probability.
NOTHING = -20.0


def floor_height(scene: Scene) -> float:
    """World y of the floor: the lowest point of the scene's roots (0 when it has none)."""
    roots = scene.roots()
    return min(float(o.world_bbox()[0][1]) for o in roots) if roots else 0.0


def _box_distances(lo: np.ndarray, hi: np.ndarray, point: np.ndarray) -> np.ndarray:
    """Distances (metres) from ``point`` to axis-aligned boxes (n, 3) — 0 inside."""
    return np.linalg.norm(np.maximum(0.0, np.maximum(lo - point, point - hi)), axis=1)


class Boxes:
    """The world boxes of a scene's supported objects (:func:`scenesuggest.scenes.frames.world_bboxes`), with their
    ids and parents: what the descriptors and the neighbourhood of a click are measured against."""

    def __init__(self, objects: list):
        self.objects = objects
        self.parents = [o.parent for o in objects]
        self.ids = [o.id for o in objects]
        if objects:
            self.lo, self.hi = frames.world_bboxes([o.transform for o in objects], [o.size for o in objects])
        else:
            self.lo = self.hi = np.zeros((0, 3))

    def distances(self, point) -> np.ndarray:
        return _box_distances(self.lo, self.hi, np.asarray(point, dtype=float))


def describe_click(scene: Scene, parent, point, normal, exclude: str | None = None, floor: float | None = None,
                   walls=None, boxes: Boxes | None = None) -> dict[str, float]:
    """The descriptors of a click on ``parent`` at ``point`` with ``normal`` (see the module docstring);
    ``exclude``: an object not to count as a neighbour (the object a training record is about); ``floor``,
    ``walls`` and ``boxes`` (of the scene's supported objects): when already at hand."""
    point, normal = np.asarray(point, dtype=float), np.asarray(normal, dtype=float)
    inv = np.linalg.inv(parent.transform)
    local = frames.apply(inv, point[None])[0]
    size = np.asarray(parent.size, dtype=float)
    half = np.maximum(size / 2, 1e-6)
    centre = np.array([0.0, size[1] / 2, 0.0])
    axis = int(np.argmax(np.abs(frames.direction_in_frame(parent.transform, normal[None])[0])))
    tangent = [a for a in range(3) if a != axis]
    edge = float(np.max(np.abs(local - centre)[tangent] / half[tangent]))
    dims = size * np.linalg.norm(parent.transform[:3, :3], axis=0)
    area = float(dims[0] * dims[2]) if parent.category == ROOM and axis == 1 else float(np.prod(dims[tangent]))
    wall = nearest_wall(room_walls(scene) if walls is None else walls, point)
    boxes = boxes if boxes is not None else Boxes([o for o in scene if o.parent is not None])
    on = np.array([p == parent.id and i != exclude for p, i in zip(boxes.parents, boxes.ids, strict=True)], dtype=bool)
    free = min(NO_SIBLING_M, float(boxes.distances(point)[on].min())) if on.any() else NO_SIBLING_M
    return {"height": float(point[1] - (floor_height(scene) if floor is None else floor)), "edge": edge,
            "wall": float(wall[1]) if wall is not None else NO_WALL_M, "area": math.log(max(area, 1e-4)),
            "free": free}


def _near(categories: np.ndarray, distances: np.ndarray, skip: int | None = None) -> np.ndarray:
    """The distinct ``categories`` (candidate indices) of boxes within NEAR_M (``skip``: a box not to count)."""
    keep = distances < NEAR_M
    if skip is not None:
        keep[skip] = False
    return np.unique(categories[keep])


class ContextStats:
    """Counts of the context of each candidate category in a corpus (see the module docstring).

    Attributes
    ----------
    names : list of str
        The candidate categories, in the engine's order (the columns of every array).
    hist : ndarray of shape (descriptors, candidates, max bins), float32
        Instances per bin of each descriptor (in the order of DESCRIPTORS; unused bins are 0).
    instances : ndarray of shape (candidates,), float32
        Supported instances.
    scenes, scene_pairs : ndarray of shape (candidates,) and (candidates, candidates), float32
        Scenes holding the category; scenes holding both (row: the category present, column: the candidate).
    parents, parent_pairs : ndarray of shape (candidates,) and (candidates, candidates), float32
        Parent instances carrying the category; carrying both.
    near, near_pairs : ndarray of shape (candidates,) and (candidates, candidates), float32
        Instances with the category within NEAR_M; of which the candidate (column).
    type_scenes : ndarray of shape (scene types, candidates), float32
        Scenes of each type (in the order of ``scene_types``) holding the category; ``type_totals`` (scene types,):
        scenes of each type.
    """

    ARRAY_NAMES = ("hist", "instances", "scenes", "scene_pairs", "parents", "parent_pairs", "near", "near_pairs",
                   "type_scenes", "type_totals")

    def __init__(self, names: list[str], scene_types: list[str], arrays: dict[str, np.ndarray]):
        self.names = list(names)
        self.scene_types = list(scene_types)
        self.index = {n: i for i, n in enumerate(self.names)}
        self.type_index = {t: i for i, t in enumerate(self.scene_types)}
        self.arrays = {k: np.asarray(arrays[k], dtype=np.float32) for k in self.ARRAY_NAMES}
        for k, v in self.arrays.items():
            setattr(self, k, v)
        totals = self.hist.sum(axis=1)  # (descriptors, bins)
        self.global_hist = totals / np.maximum(totals.sum(axis=1, keepdims=True), 1.0)
        self.base_scene = np.log((self.scenes + COUNT_PRIOR) / (max(float(self.type_totals.sum()), 0.0) + 1.0))
        self.base_parent = np.log((self.parents + COUNT_PRIOR) / (float(self.parents.sum()) + 1.0))
        self.base_instance = np.log((self.instances + COUNT_PRIOR) / (float(self.instances.sum()) + 1.0))
        # what every click reads the same: each descriptor's instances per candidate, the base rates' pseudo-counts
        self._hist_totals = self.hist.sum(axis=2)
        self._prior = {key: COUNT_PRIOR * np.exp(base) for key, base in
                       (("scene", self.base_scene), ("parent", self.base_parent), ("near", self.base_instance))}

    @classmethod
    def fit(cls, scenes: list[Scene], names: list[str], scene_types: list[str] | None = None) -> ContextStats:
        """Count the context of every category of ``names`` in ``scenes``; ``scene_types`` numbers the scene types
        (default: those of ``scenes``, sorted) — give every fold of one training the same list, so that a scene
        type's number means the same in all of their rows."""
        n = len(names)
        index = {c: i for i, c in enumerate(names)}
        scene_types = sorted(set(scene_types or ()) | {s.scene_type for s in scenes})
        t_index = {t: i for i, t in enumerate(scene_types)}
        bins = max(len(e) for e in EDGES.values()) + 1
        a = {"hist": np.zeros((len(DESCRIPTORS), n, bins)), "instances": np.zeros(n), "scenes": np.zeros(n),
             "scene_pairs": np.zeros((n, n)), "parents": np.zeros(n), "parent_pairs": np.zeros((n, n)),
             "near": np.zeros(n), "near_pairs": np.zeros((n, n)), "type_scenes": np.zeros((len(scene_types), n)),
             "type_totals": np.zeros(len(scene_types))}
        for scene in scenes:
            supported = [o for o in scene if o.parent is not None and o.category in index]
            present = np.unique(np.array([index[o.category] for o in supported], dtype=np.int64))
            a["scenes"][present] += 1
            a["scene_pairs"][np.ix_(present, present)] += 1
            a["type_scenes"][t_index[scene.scene_type], present] += 1
            a["type_totals"][t_index[scene.scene_type]] += 1
            carried: dict[str, set[int]] = {}
            for o in supported:
                carried.setdefault(o.parent, set()).add(index[o.category])
            for kids in carried.values():
                k = np.array(sorted(kids), dtype=np.int64)
                a["parents"][k] += 1
                a["parent_pairs"][np.ix_(k, k)] += 1
            floor, walls, boxes = floor_height(scene), room_walls(scene), Boxes(supported)
            categories = np.array([index[o.category] for o in supported], dtype=np.int64)
            for j, o in enumerate(supported):
                if o.contact_point is None or o.contact_normal is None:
                    continue
                c = index[o.category]
                a["instances"][c] += 1
                near = _near(categories, boxes.distances(o.contact_point), skip=j)
                a["near"][near] += 1
                a["near_pairs"][near, c] += 1
                d = describe_click(scene, scene.objects[o.parent], o.contact_point, o.contact_normal, o.id, floor,
                                   walls, boxes)
                for k, name in enumerate(DESCRIPTORS):
                    a["hist"][k, c, np.searchsorted(EDGES[name], d[name])] += 1
        return cls(names, scene_types, a)

    def features(self, scene: Scene, parent, point, normal, scene_type: str) -> tuple[dict[str, np.ndarray], dict]:
        """({feature: value per candidate}, the click's descriptors) for a click (see the module docstring)."""
        n = len(self.names)
        everything = Boxes([o for o in scene if o.parent is not None])
        d = describe_click(scene, parent, point, normal, boxes=everything)
        is_known = np.array([o.category in self.index for o in everything.objects], dtype=bool)
        known = [o for o, k in zip(everything.objects, is_known, strict=True) if k]
        out: dict[str, np.ndarray] = {}
        for k, name in enumerate(DESCRIPTORS):
            b = int(np.searchsorted(EDGES[name], d[name]))
            h = self.hist[k]
            out[f"likely_{name}"] = np.log((h[:, b] + HIST_PRIOR * self.global_hist[k, b] + 1e-3)
                                           / (self._hist_totals[k] + HIST_PRIOR))
        in_scene = np.array([self.index[o.category] for o in known], dtype=np.int64)
        on_parent = in_scene[np.array([o.parent == parent.id for o in known], dtype=bool)] if known else in_scene
        near = _near(in_scene, everything.distances(point)[is_known])
        for key, present, pairs, counts, base in (
                ("scene", np.unique(in_scene), self.scene_pairs, self.scenes, self.base_scene),
                ("parent", np.unique(on_parent), self.parent_pairs, self.parents, self.base_parent),
                ("near", near, self.near_pairs, self.near, self.base_instance)):
            if len(present):
                given = np.log((pairs[present] + self._prior[key]) / (counts[present, None] + COUNT_PRIOR))
                out[f"given_{key}_max"], out[f"given_{key}_mean"] = given.max(axis=0), given.mean(axis=0)
            else:  # nothing to condition on: the scene's base rate; an empty parent or nothing near: NOTHING
                out[f"given_{key}_max"] = out[f"given_{key}_mean"] = base if key == "scene" else np.full(n, NOTHING)
        out["given_scene_lift"] = (out["given_scene_mean"] - self.base_scene) if len(in_scene) else np.zeros(n)
        out["frequency"] = self.base_instance
        out["in_scenes"] = self.base_scene
        t = self.type_index.get(scene_type)
        out["in_scene_type"] = (np.log((self.type_scenes[t] + COUNT_PRIOR) / (self.type_totals[t] + 1.0))
                                if t is not None else self.base_scene)
        out["count_in_scene"] = np.bincount(in_scene, minlength=n).astype(float)
        out["count_on_parent"] = np.bincount(on_parent, minlength=n).astype(float)
        for name, value in d.items():
            out[f"click_{name}"] = np.full(n, value)
        out["click_objects_on_parent"] = np.full(n, float(len(on_parent)))
        out["click_objects_in_scene"] = np.full(n, float(len(in_scene)))
        out["click_categories_near"] = np.full(n, float(len(near)))
        return out, d
