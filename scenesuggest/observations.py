"""What the priors learn from: every support edge of a corpus and its context, as plain records.

For each supported object ``o`` (category ``C``, parent ``p``, surface type ``t``, face ``f``, scene type
``s``) there is one :class:`Support` record, and one :class:`Pair` for each reference ``r`` in its
context — the parent (relation ``parent``), every other object on the same parent (``sibling``) and, on an
upward surface, the nearest wall of the room (``wall``, reference category :data:`WALL`) — holding:

* the offset δ of ``o``'s contact point from ``r`` on the support plane, in ``r``'s frame (a wall: the distance
  from it, as for references without a front);
* θ, the heading of ``o`` relative to ``r``'s front (a wall's front is its inward normal; on vertical planes
  the plane's up, see :mod:`scenesuggest.poses`);
* φ, the heading of ``o`` relative to the bearing from ``o`` to ``r``'s centre (horizontal planes only):
  chairs on four sides of a table have four θ but one φ.

Angles are radians in [0, 2π); NaN where undefined. ``Support.alpha`` is the turn from the canonical pose of
``o``'s face on that plane (:func:`scenesuggest.poses.zero_heading`), what the canonical orientation prior
counts. ``scene`` numbers the scene in the training list, so that statistics can leave a scene (and its
near-copies) out.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass

import numpy as np

from . import poses
from .scene import ObjectInstance, Scene
from .walls import Wall, nearest_wall, room_walls

RELATIONS = ("sibling", "parent", "wall")
WALL = "Wall"
#: A reference without a front (radial) has a footprint this close to square or round.
RADIAL_ASPECT = 1.1
#: Bearings to references whose centre is closer than this (metres, in the plane) are undefined.
MIN_BEARING_M = 0.02


def is_radial(size) -> bool:
    """Whether a reference has no front: its footprint is nearly square (aspect below RADIAL_ASPECT)."""
    sx, _, sz = size
    return max(sx, sz) / max(min(sx, sz), 1e-9) < RADIAL_ASPECT


@dataclass(frozen=True)
class Support:
    scene_type: str
    category: str
    parent_category: str
    surface_type: str
    face: str
    model_id: str
    size: tuple[float, float, float]
    heading: float = float("nan")  # radians in [0, 2π) about the support normal (see poses)
    alpha: float = float("nan")  # heading − the canonical heading of the face on the plane
    scene: int = 0


@dataclass(frozen=True)
class Pair:
    scene_type: str
    category: str
    ref_category: str
    relation: str
    surface_type: str
    offset: tuple[float, float]
    theta: float  # radians in [0, 2π); NaN when the object's heading is undefined
    phi: float = float("nan")
    scene: int = 0
    support: int = 0  # index of the pair's Support record
    radial: bool = False  # the reference has no front (θ is then measured from the bearing to it)


def centre(o: ObjectInstance) -> np.ndarray:
    """The world centre of an object's box."""
    lo, hi = o.world_bbox()
    return (lo + hi) / 2


def context(scene: Scene, o: ObjectInstance) -> list[tuple[ObjectInstance, str]]:
    """The references of an object on its parent: the parent itself and the parent's other children."""
    refs = [(scene.objects[o.parent], "parent")]
    refs += [(q, "sibling") for q in scene.children(o.parent) if q.id != o.id]
    return refs


def bearing(point, normal, ref: ObjectInstance) -> float:
    """Heading (radians) of the direction from ``point`` to ``ref``'s centre on a horizontal plane; NaN on
    vertical planes or when the centre is within MIN_BEARING_M."""
    if not poses.is_horizontal(normal):
        return float("nan")
    d = centre(ref) - np.asarray(point, dtype=float)
    n = np.asarray(normal, dtype=float) / np.linalg.norm(normal)
    if np.linalg.norm(d - np.dot(d, n) * n) < MIN_BEARING_M:
        return float("nan")
    return poses.heading(d, n)


def _relative(heading: float, reference: float) -> float:
    return float(poses.wrap(heading - reference)) if not (math.isnan(heading) or math.isnan(reference)) else math.nan


def pair_geometry(point, normal, heading: float, ref: ObjectInstance) -> tuple[np.ndarray, float, float]:
    """(δ, θ, φ) of an object at ``point`` with ``heading`` on a plane with ``normal`` relative to ``ref``."""
    radial = is_radial(ref.size)
    offset = poses.plane_offset(point, normal, ref.transform, radial)
    theta = _relative(heading, poses.reference_heading(point, normal, ref.transform, radial))
    return offset, theta, _relative(heading, bearing(point, normal, ref))


def wall_reference(scene: Scene, point, normal) -> tuple[Wall, float] | None:
    """The nearest wall of a point on an upward surface, and its distance (metres); None elsewhere."""
    n = np.asarray(normal, dtype=float)
    if not poses.is_horizontal(n) or n[1] <= 0:
        return None
    return nearest_wall(room_walls(scene), point)


def wall_heading(wall: Wall, normal) -> float:
    """Heading (radians) of a wall's inward normal on a horizontal plane."""
    return poses.heading(wall.heading_normal, normal)


def scene_observations(scene: Scene, index: int = 0, first: int = 0) -> tuple[list[Support], list[Pair]]:
    """The records of one scene (``index``: its number; ``first``: the number of its first Support record)."""
    supports, pairs = [], []
    for o in scene:
        if o.parent is None or o.surface_type is None or o.attachment_face is None or o.contact_point is None:
            continue
        parent = scene.objects[o.parent]
        normal = np.asarray(o.contact_normal, dtype=float)
        heading = poses.object_heading(o.transform, o.attachment_face, normal)
        h = float(poses.wrap(heading)) if not math.isnan(heading) else math.nan
        supports.append(Support(scene.scene_type, o.category, parent.category, o.surface_type, o.attachment_face,
                                o.model_id, tuple(o.size), h,
                                _relative(heading, poses.zero_heading(o.attachment_face, normal)), index))
        support = first + len(supports) - 1
        for ref, relation in context(scene, o):
            offset, theta, phi = pair_geometry(o.contact_point, normal, heading, ref)
            pairs.append(Pair(scene.scene_type, o.category, ref.category, relation, o.surface_type,
                              (float(offset[0]), float(offset[1])), theta, phi, index, support,
                              is_radial(ref.size)))
        wall = wall_reference(scene, o.contact_point, normal)
        if wall is not None:
            pairs.append(Pair(scene.scene_type, o.category, WALL, "wall", o.surface_type, (wall[1], 0.0),
                              _relative(heading, wall_heading(wall[0], normal)), math.nan, index, support))
    return supports, pairs


def corpus_observations(scenes: Iterable[Scene]) -> tuple[list[Support], list[Pair]]:
    supports, pairs = [], []
    for i, scene in enumerate(scenes):
        s, p = scene_observations(scene, i, len(supports))
        supports += s
        pairs += p
    return supports, pairs
