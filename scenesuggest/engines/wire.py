"""What the ``http`` engine and an external engine say to each other: the query document, the answer document,
their JSON Schemas (published in the study API's OpenAPI document) and the strict reading of an answer.

An answer is read by the rules of :mod:`.http`'s docstring (a placeholder category is refused, as
:mod:`scenesuggest.suggestion.suggestable` decides for every engine); a broken one raises
:class:`NoUsableAnswer` naming the first broken rule (``invalid answer: suggestions[3].placement is not a rigid
transform``) — never the engine's address or its bytes.
"""

from __future__ import annotations

import math
from collections.abc import Collection, Mapping
from dataclasses import replace

import numpy as np

from ..scenes import frames, poses
from ..scenes.scene import Scene
from ..scenes.scene_json import finite, scene_to_dict
from ..suggestion.suggest import MODES, Suggestion
from ..suggestion.suggestable import suggestable

PROTOCOL_VERSION = 1
#: The most objects of a participant's scene a query carries (:func:`query_scene`).
MAX_QUERY_OBJECTS = 400
#: A placement's rotation must be orthonormal to this tolerance, and its origin this close to the click (metres).
RIGID_TOLERANCE = 1e-4
MAX_DISTANCE_M = 100.0
MAX_TERMS = 16
MAX_MODELS = 64
MAX_TEXT = 200
_FACE_NORMALS = np.array([frames.FACE_NORMALS[f] for f in frames.FACES], dtype=float)

_NUMBER = {"type": "number"}
_VEC3 = {"type": "array", "items": _NUMBER, "minItems": 3, "maxItems": 3}
QUERY_SCHEMA = {
    "type": "object", "title": "EngineQuery",
    "description": "What the study server POSTs to an HTTP engine for one click (metres, world frame, +Y up).",
    "required": ["protocol", "scene", "parent", "point", "normal", "surface_type", "scene_type", "mode", "top",
                 "categories"],
    "properties": {
        "protocol": {"const": PROTOCOL_VERSION},
        "scene": {"type": "object", "description": "the participant's scene in the native scene format "
                                                   "(scenesuggest-scene, version 1); beyond "
                                                   f"{MAX_QUERY_OBJECTS} objects, the clicked object with what "
                                                   "supports it and what stands on it, then the objects nearest "
                                                   "the click"},
        "objects_left_out": {"type": "integer", "minimum": 0,
                             "description": "how many objects of the participant's scene the summary leaves out"},
        "parent": {"type": "string", "description": "id of the clicked object"},
        "point": {**_VEC3, "description": "the clicked point"},
        "normal": {**_VEC3, "description": "the unit surface normal there"},
        "surface_type": {"type": "string", "enum": ["up_interior", "up_exterior", "down_interior", "down_exterior",
                                                    "vertical_interior", "vertical_exterior"]},
        "scene_type": {"type": "string"},
        "mode": {"type": "string", "enum": list(MODES),
                 "description": "basic: canonical pose; full: also oriented"},
        "top": {"type": "integer", "minimum": 1, "description": "at most this many suggestions are read"},
        "categories": {"type": "array", "items": {"type": "string"},
                       "description": "the categories the answer may hold (those the study's library can place)"},
    },
}
ANSWER_SCHEMA = {
    "type": "object", "title": "EngineAnswer", "required": ["suggestions"],
    "description": "An HTTP engine's answer: suggestions, best first.",
    "properties": {"suggestions": {"type": "array", "items": {
        "type": "object", "required": ["category", "score", "placement"],
        "properties": {
            "category": {"type": "string", "description": "one of the query's categories, at most once"},
            "score": {**_NUMBER, "description": "finite; higher is better"},
            "placement": {"type": "array", "items": _NUMBER, "minItems": 16, "maxItems": 16,
                          "description": "rigid 4×4 canonical → world transform, column-major"},
            "attachment_face": {"type": "string", "enum": list(frames.FACES)},
            "heading_deg": _NUMBER,
            "models": {"type": "array", "items": {"type": "string"}, "maxItems": MAX_MODELS,
                       "description": "model ids of the category, best first (default: the category's models)"},
            "terms": {"type": "object", "additionalProperties": _NUMBER, "maxProperties": MAX_TERMS,
                      "description": "why the category got its rank (name → number)"},
        }}}},
}


def answer_item(s: Suggestion, models: int = MAX_MODELS) -> dict:
    """A suggestion as an engine's answer carries it (ANSWER_SCHEMA): :meth:`Suggestion.to_dict` without the rank
    (the answer's order is the ranking) and the notes, naming at most ``models`` of its models."""
    d = s.to_dict()
    return {k: d[k] for k in ANSWER_SCHEMA["properties"]["suggestions"]["items"]["properties"]} | {
        "models": d["models"][:models]}


class NoUsableAnswer(Exception):
    """The external engine gave no usable answer; ``str()`` is the reason, without the URL."""


def query_document(prep, mode: str, top: int, categories: Collection[str]) -> dict:
    """The JSON document POSTed for a prepared query (:data:`QUERY_SCHEMA`): the scene summarised to at most
    MAX_QUERY_OBJECTS objects (:func:`query_scene`)."""
    scene, left_out = query_scene(prep.query.scene, prep.query.parent_id, prep.point)
    return {"protocol": PROTOCOL_VERSION, "scene": scene_to_dict(scene), "objects_left_out": left_out,
            "parent": prep.query.parent_id,
            "point": [float(x) for x in prep.point], "normal": [float(x) for x in prep.normal],
            "surface_type": prep.surface_type, "scene_type": prep.scene_type, "mode": mode, "top": int(top),
            "categories": sorted(categories)}


def query_scene(scene: Scene, parent_id: str, point) -> tuple[Scene, int]:
    """(the scene an engine is sent, how many objects it leaves out): the whole scene up to MAX_QUERY_OBJECTS
    objects; beyond, the clicked object with what supports it and what stands on it, then the others nearest the
    click (metres, world frame; each with what supports it, so that the summary is a scene), so that the size of
    a query — and an engine's time — does not grow with what a participant piles up."""
    if len(scene) <= MAX_QUERY_OBJECTS:
        return scene, 0
    objects = scene.objects
    kept: dict[str, None] = {}

    def keep(object_id: str | None) -> None:
        chain = []
        while object_id is not None and object_id not in kept and object_id in objects:
            chain.append(object_id)
            object_id = objects[object_id].parent
        if len(kept) + len(chain) <= MAX_QUERY_OBJECTS:
            kept.update(dict.fromkeys(reversed(chain)))

    keep(parent_id)
    for o in scene.children(parent_id):
        keep(o.id)
    ids = list(objects)
    centres = np.array([objects[i].transform[:3, 3] for i in ids], dtype=float)
    for k in np.argsort(np.linalg.norm(centres - np.asarray(point, dtype=float), axis=1), kind="stable"):
        if len(kept) >= MAX_QUERY_OBJECTS:
            break
        keep(ids[k])
    summary = {k: v for k, v in objects.items() if k in kept}
    return replace(scene, objects=summary), len(scene) - len(summary)


def _placements(items: list, point: np.ndarray) -> np.ndarray:
    """(n, 4, 4) placements of the answer's items, checked: 16 finite numbers each, rigid, near the click."""
    numbers = (int, float)  # JSON numbers as the parser gives them (not booleans, strings or nulls)
    for i, item in enumerate(items):
        value = item.get("placement")
        if not isinstance(value, list) or len(value) != 16 or not all(type(v) in numbers for v in value):
            raise NoUsableAnswer(f"invalid answer: suggestions[{i}].placement is not 16 finite numbers")
    m = np.array([item["placement"] for item in items], dtype=float).reshape(-1, 4, 4).transpose(0, 2, 1)
    if not np.isfinite(m).all():
        raise NoUsableAnswer("invalid answer: a placement is not 16 finite numbers")
    r = m[:, :3, :3]
    bad = ((np.abs(m[:, 3] - [0, 0, 0, 1]).max(axis=1) > RIGID_TOLERANCE)
           | (np.abs(np.einsum("nji,njk->nik", r, r) - np.eye(3)).max(axis=(1, 2)) > RIGID_TOLERANCE)
           | (np.linalg.det(r) <= 0)) if len(m) else np.zeros(0, dtype=bool)
    if bad.any():
        raise NoUsableAnswer(f"invalid answer: suggestions[{int(np.argmax(bad))}].placement is not a rigid "
                                "transform")
    far = np.linalg.norm(m[:, :3, 3] - point, axis=1) > MAX_DISTANCE_M if len(m) else np.zeros(0, dtype=bool)
    if far.any():
        raise NoUsableAnswer(f"invalid answer: suggestions[{int(np.argmax(far))}].placement is more than "
                                f"{MAX_DISTANCE_M:g} m from the click")
    return m


def parse_answer(doc, allowed: Collection[str], models: Mapping[str, tuple[str, ...]], point, normal,
                 max_suggestions: int) -> list[Suggestion]:
    """The suggestions of an answer document, checked by the rules of the module docstring; raises
    :class:`NoUsableAnswer` naming the first broken rule (``suggestions[3].placement: …``)."""
    if not isinstance(doc, dict) or not isinstance(doc.get("suggestions"), list):
        raise NoUsableAnswer("invalid answer: expected {\"suggestions\": [...]}")
    items = doc["suggestions"]
    if len(items) > max_suggestions:
        raise NoUsableAnswer(f"invalid answer: {len(items)} suggestions, at most {max_suggestions}")
    for i, item in enumerate(items):
        if not isinstance(item, dict):
            raise NoUsableAnswer(f"invalid answer: suggestions[{i}] is not an object")
    placements = _placements(items, np.asarray(point, dtype=float))
    # the face each placement turns to the clicked surface: its outward normal closest to −normal (canonical frame)
    inward = np.einsum("nji,j->ni", placements[:, :3, :3], -np.asarray(normal, dtype=float))
    touching_faces = np.argmax(inward @ _FACE_NORMALS.T, axis=1) if len(items) else np.zeros(0, dtype=np.int64)
    out, seen = [], set()
    for i, (item, placement) in enumerate(zip(items, placements, strict=True)):
        where = f"suggestions[{i}]"
        category = item.get("category")
        if isinstance(category, str) and not suggestable(category):
            raise NoUsableAnswer(f"invalid answer: {where}.category {category!r} is a placeholder, which no one "
                                    "can place")
        if not isinstance(category, str) or category not in allowed:
            raise NoUsableAnswer(f"invalid answer: {where}.category is not one the query allows")
        if category in seen:
            raise NoUsableAnswer(f"invalid answer: {where}.category appears twice")
        seen.add(category)
        if not finite(item.get("score")):
            raise NoUsableAnswer(f"invalid answer: {where}.score is not a finite number")
        touching = frames.FACES[touching_faces[i]]
        face = item.get("attachment_face", touching)
        if face not in frames.FACES:
            raise NoUsableAnswer(f"invalid answer: {where}.attachment_face is not one of {', '.join(frames.FACES)}")
        if face != touching:
            raise NoUsableAnswer(f"invalid answer: {where}.attachment_face is not the face its placement turns to "
                                    "the clicked surface")
        heading = item.get("heading_deg")
        if heading is None:
            heading = math.degrees(float(poses.wrap(poses.object_heading(placement, face, normal))))
        if not finite(heading):
            raise NoUsableAnswer(f"invalid answer: {where}.heading_deg is not a finite number (nor follows from "
                                    "the placement)")
        known = models.get(category, ())
        chosen = item.get("models", list(known[:MAX_MODELS]))
        if not isinstance(chosen, list) or len(chosen) > MAX_MODELS:
            raise NoUsableAnswer(f"invalid answer: {where}.models is not a list of at most {MAX_MODELS} ids")
        if not all(isinstance(m, str) for m in chosen) or not set(chosen) <= set(known):
            raise NoUsableAnswer(f"invalid answer: {where}.models are not models of {category!r}")
        terms = item.get("terms", {})
        if (not isinstance(terms, dict) or len(terms) > MAX_TERMS
                or not all(isinstance(k, str) and len(k) <= MAX_TEXT and finite(v) for k, v in terms.items())):
            raise NoUsableAnswer(f"invalid answer: {where}.terms must map at most {MAX_TERMS} names to numbers")
        out.append(Suggestion(rank=i + 1, category=category, score=float(item["score"]),
                              terms={k: float(v) for k, v in terms.items()}, placement=placement,
                              attachment_face=face, heading_deg=float(heading), models=tuple(chosen) or known))
    return out
