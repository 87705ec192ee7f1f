"""What the priors learn from: every support edge of a corpus and its context, as plain records.

For each supported object ``o`` (category ``C``, parent ``p``, surface type ``t``, face ``f``, scene type
``s``) there is one :class:`Support` record, and one :class:`Pair` for each reference ``r`` in its
context — the parent (relation ``parent``) and every other object on the same parent (``sibling``) —
holding the offset δ of ``o``'s contact point from ``r`` on the support plane, in ``r``'s frame, and the
relative heading θ of ``o`` with respect to ``r`` (see :mod:`scenesuggest.poses`).
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass

import numpy as np

from . import poses
from .scene import ObjectInstance, Scene

RELATIONS = ("sibling", "parent")
#: A reference without a front (radial) has a footprint this close to square or round.
RADIAL_ASPECT = 1.1


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


@dataclass(frozen=True)
class Pair:
    scene_type: str
    category: str
    ref_category: str
    relation: str
    surface_type: str
    offset: tuple[float, float]
    theta: float  # radians in [0, 2π); NaN when the object's heading is undefined


def context(scene: Scene, o: ObjectInstance) -> list[tuple[ObjectInstance, str]]:
    """The references of an object on its parent: the parent itself and the parent's other children."""
    refs = [(scene.objects[o.parent], "parent")]
    refs += [(q, "sibling") for q in scene.children(o.parent) if q.id != o.id]
    return refs


def pair_geometry(point, normal, heading: float, ref: ObjectInstance) -> tuple[np.ndarray, float]:
    """(δ, θ) of an object at ``point`` with ``heading`` on a plane with ``normal`` relative to ``ref``."""
    radial = is_radial(ref.size)
    offset = poses.plane_offset(point, normal, ref.transform, radial)
    theta = heading - poses.reference_heading(point, normal, ref.transform, radial)
    return offset, float(poses.wrap(theta)) if not math.isnan(theta) else float("nan")


def scene_observations(scene: Scene) -> tuple[list[Support], list[Pair]]:
    supports, pairs = [], []
    for o in scene:
        if o.parent is None or o.surface_type is None or o.attachment_face is None or o.contact_point is None:
            continue
        parent = scene.objects[o.parent]
        supports.append(Support(scene.scene_type, o.category, parent.category, o.surface_type, o.attachment_face,
                                o.model_id, tuple(o.size)))
        normal = np.asarray(o.contact_normal, dtype=float)
        heading = poses.object_heading(o.transform, o.attachment_face, normal)
        for ref, relation in context(scene, o):
            offset, theta = pair_geometry(o.contact_point, normal, heading, ref)
            pairs.append(Pair(scene.scene_type, o.category, ref.category, relation, o.surface_type,
                              (float(offset[0]), float(offset[1])), theta))
    return supports, pairs


def corpus_observations(scenes: Iterable[Scene]) -> tuple[list[Support], list[Pair]]:
    supports, pairs = [], []
    for scene in scenes:
        s, p = scene_observations(scene)
        supports += s
        pairs += p
    return supports, pairs
