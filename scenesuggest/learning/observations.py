"""What the priors learn from: every support edge of a corpus and its context, as plain records.

For each supported object ``o`` (category ``C``, parent ``p``, surface type ``t``, face ``f``, scene type
``s``) there is one :class:`Support` record, and one :class:`Pair` for each reference ``r`` in its
context — the parent (relation ``parent``), every other object on the same parent (``sibling``) and, on an
upward surface, the nearest wall of the room when the object stands at it (``wall``, reference category
:data:`WALL`, :func:`near_wall`) — holding:

* the offset δ of ``o``'s contact point from ``r`` on the support plane, in ``r``'s frame (a wall: the distance
  from it, as for references without a front);
* θ, the heading of ``o`` relative to ``r``'s front (a wall's front is its inward normal; on vertical planes
  the plane's up, see :mod:`scenesuggest.scenes.poses`);
* φ, the heading of ``o`` relative to the bearing from ``o`` towards ``r`` (:func:`bearing`; horizontal planes
  only): chairs on four sides of a table have four θ but one φ.

Angles are radians in [0, 2π); NaN where undefined. ``Support.alpha`` is the turn from the canonical pose of
``o``'s face on that plane (:func:`scenesuggest.scenes.poses.zero_heading`), what the canonical orientation prior
counts. ``scene`` numbers the scene in the training list, so that statistics can leave a scene (and its
near-copies) out.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass

import numpy as np

from ..scenes import poses
from ..scenes.scene import ObjectInstance, Scene
from ..scenes.walls import Wall, nearest_wall, room_walls

RELATIONS = ("sibling", "parent", "wall")
WALL = "Wall"
#: The entity that pools every category (wall statistics only, see :mod:`scenesuggest.learning.pair_priors`).
POOLED = "*"
#: A reference without a front (radial) has a footprint this close to square or round.
RADIAL_ASPECT = 1.1
#: Bearings to references whose centre is closer than this (metres, in the plane) are undefined.
MIN_BEARING_M = 0.02
#: The nearest wall is a reference of an object whose footprint (its shorter half-side from the contact point)
#: comes this close to it: "back to the wall" is a statement about objects at a wall.
WALL_GAP_M = 0.3


def is_radial(size):
    """Whether a reference has no front: its footprint is nearly square (aspect below RADIAL_ASPECT). ``size``:
    one (x, y, z) extent in metres, or an array (…, 3) of them for an array of answers."""
    size = np.asarray(size, dtype=float)
    sx, sz = size[..., 0], size[..., 2]
    return np.maximum(sx, sz) / np.maximum(np.minimum(sx, sz), 1e-9) < RADIAL_ASPECT


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


def context(scene: Scene, o: ObjectInstance) -> list[tuple[ObjectInstance, str]]:
    """The references of an object on its parent: the parent itself and the parent's other children."""
    refs = [(scene.objects[o.parent], "parent")]
    refs += [(q, "sibling") for q in scene.children(o.parent) if q.id != o.id]
    return refs


def bearings(points, normals, ref_transforms, ref_sizes) -> np.ndarray:
    """(N,) headings (radians) of the directions from points towards references on horizontal planes: to the
    nearest point of a reference's footprint when the point lies outside it (a chair at a long table faces the
    table's edge, not its far-away centre), to its centre when inside; NaN on vertical planes or within
    MIN_BEARING_M."""
    t = np.asarray(ref_transforms, dtype=float).reshape(-1, 4, 4)
    p = np.asarray(points, dtype=float).reshape(-1, 3)
    normals = np.asarray(normals, dtype=float)
    n = normals.reshape(-1, 3)
    n = n / np.linalg.norm(n, axis=1, keepdims=True)
    size = np.asarray(ref_sizes, dtype=float).reshape(-1, 3)
    linear = t[:, :3, :3]
    scale = np.linalg.norm(linear, axis=1)  # of each column: the frame's scale per axis
    r = linear / scale[:, None, :]
    half = size * scale / 2
    middle = linear[:, :, 1] * (size[:, 1:2] * 0.5) + t[:, :3, 3]  # the box's centre
    local = poses.in_frames(r, p - middle)
    nearest = np.clip(local, -half, half)
    outside = (np.abs(nearest[:, 0] - local[:, 0]) > 1e-9) | (np.abs(nearest[:, 2] - local[:, 2]) > 1e-9)
    target = np.where(outside[:, None], (r @ nearest[:, :, None])[:, :, 0] + middle, middle)
    d = target - p
    flat = d - (d * n).sum(axis=1, keepdims=True) * n
    h = poses.headings(d, normals if normals.size == 3 else n)
    horizontal = np.abs(n[:, 1]) > poses.HORIZONTAL_COS
    return np.where(horizontal & (np.linalg.norm(flat, axis=1) >= MIN_BEARING_M), h, np.nan)


def bearing(point, normal, ref: ObjectInstance) -> float:
    """:func:`bearings` from one point to one reference."""
    return float(bearings(point, normal, ref.transform, ref.size)[0])


def _relative(heading: float, reference: float) -> float:
    return float(poses.wrap(heading - reference)) if not (math.isnan(heading) or math.isnan(reference)) else math.nan


def wall_reference(scene: Scene, point, normal) -> tuple[Wall, float] | None:
    """The nearest wall of a point on an upward surface, and its distance (metres); None elsewhere."""
    n = np.asarray(normal, dtype=float)
    if not poses.is_horizontal(n) or n[1] <= 0:
        return None
    return nearest_wall(room_walls(scene), point)


def near_wall(distance: float, size):
    """Whether an object of canonical ``size`` whose contact point is ``distance`` (metres) from a wall stands at
    it. ``size``: one (x, y, z) extent in metres, or an array (…, 3) of them for an array of answers."""
    size = np.asarray(size, dtype=float)
    return distance - np.minimum(size[..., 0], size[..., 2]) / 2 <= WALL_GAP_M


def wall_heading(wall: Wall, normal) -> float:
    """Heading (radians) of a wall's inward normal on a horizontal plane."""
    return poses.heading(wall.heading_normal, normal)


def scene_observations(scene: Scene, index: int = 0, first: int = 0) -> tuple[list[Support], list[Pair]]:
    """The records of one scene (``index``: its number; ``first``: the number of its first Support record);
    the geometry of all its pairs is computed at once."""
    supports, supported, rows = [], [], []  # rows: (support number, object, reference, relation)
    for o in scene:
        if o.parent is None or o.surface_type is None or o.attachment_face is None or o.contact_point is None:
            continue
        supported.append(o)
        normal = np.asarray(o.contact_normal, dtype=float)
        heading = poses.object_heading(o.transform, o.attachment_face, normal)
        h = float(poses.wrap(heading)) if not math.isnan(heading) else math.nan
        supports.append(Support(scene.scene_type, o.category, scene.objects[o.parent].category, o.surface_type,
                                o.attachment_face, o.model_id, tuple(o.size), h,
                                _relative(heading, poses.zero_heading(o.attachment_face, normal)), index))
        rows += [(len(supports) - 1, o, ref, relation) for ref, relation in context(scene, o)]
    pairs = []
    if rows:
        point = np.array([o.contact_point for _, o, _, _ in rows], dtype=float)
        normal = np.array([o.contact_normal for _, o, _, _ in rows], dtype=float)
        ref_t = np.array([ref.transform for _, _, ref, _ in rows], dtype=float)
        ref_size = np.array([ref.size for _, _, ref, _ in rows], dtype=float)
        radial = is_radial(ref_size)
        heading = np.array([supports[k].heading for k, _, _, _ in rows])
        offset = poses.plane_offsets(point, normal, ref_t, radial)
        theta = np.mod(heading - poses.reference_headings(point, normal, ref_t, radial), 2 * math.pi)
        phi = np.mod(heading - bearings(point, normal, ref_t, ref_size), 2 * math.pi)
        for j, (k, o, ref, relation) in enumerate(rows):
            pairs.append(Pair(scene.scene_type, o.category, ref.category, relation, o.surface_type,
                              (float(offset[j, 0]), float(offset[j, 1])), float(theta[j]), float(phi[j]), index,
                              first + k, bool(radial[j])))
    for k, (sup, o) in enumerate(zip(supports, supported, strict=True)):
        normal = np.asarray(o.contact_normal, dtype=float)
        wall = wall_reference(scene, o.contact_point, normal)
        # the instance's own footprint (scenes scale models): did it stand at the wall? At query time the same
        # rule asks whether the suggested model, at its own size, would
        if wall is not None and near_wall(wall[1], o.scaled_size()):
            pairs.append(Pair(scene.scene_type, o.category, WALL, "wall", o.surface_type, (wall[1], 0.0),
                              _relative(sup.heading, wall_heading(wall[0], normal)), math.nan, index, first + k))
    return supports, pairs


def corpus_observations(scenes: Iterable[Scene]) -> tuple[list[Support], list[Pair]]:
    supports, pairs = [], []
    for i, scene in enumerate(scenes):
        s, p = scene_observations(scene, i, len(supports))
        supports += s
        pairs += p
    return supports, pairs
