"""Context queries: a click on a parent's surface, validated, and what the engine reads from it before scoring.

From the click (world frame, metres, +Y up): the unit surface normal; the surface type
(:mod:`scenesuggest.scenes.surfaces`); the scene type — the query's own, else inferred from the objects present when
asked to (:mod:`scenesuggest.scenes.scene_types`), else the scene's; the references — the clicked parent and every
object already on it; and, on an upward surface, the nearest wall with its distance
(:func:`scenesuggest.learning.observations.wall_reference`). Errors name the query's field.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..errors import SceneSuggestError
from ..learning.observations import wall_reference
from ..scenes import surfaces
from ..scenes.scene import Scene
from ..scenes.scene_types import infer_scene_type
from ..scenes.taxonomy import Taxonomy

#: A click may lie this far (metres) outside its parent's box (or 5% of the box diagonal, if more): boxes
#: of models placed from metadata are estimates (on the Stanford corpus every contact is within 11 cm).
POINT_TOLERANCE_M = 0.15


@dataclass(frozen=True)
class ContextQuery:
    """A click on ``parent_id``'s surface at world ``point`` with surface ``normal`` (metres, +Y up)."""

    scene: Scene
    parent_id: str
    point: tuple[float, float, float]
    normal: tuple[float, float, float]
    scene_type: str | None = None


@dataclass
class Prepared:
    """A validated query and what the engine derives from it: surface and scene type, references (the
    parent and its children) and the nearest wall (with its distance, metres) of an upward surface."""

    query: ContextQuery
    point: np.ndarray
    normal: np.ndarray
    surface_type: str
    scene_type: str
    parent_category: str
    references: list[tuple[object, str]] = field(default_factory=list)
    wall: tuple[object, float] | None = None


def prepare(query: ContextQuery, taxonomy: Taxonomy, infer: bool = False) -> Prepared:
    """Validate ``query`` and derive its surface type, scene type (inferred with ``taxonomy`` when ``infer``
    and the query names none), references and nearest wall."""
    scene = query.scene
    parent = scene.objects.get(query.parent_id) if isinstance(query.parent_id, str) else None
    if parent is None:
        raise SceneSuggestError(f"no object {query.parent_id!r} in the scene", field="parent")
    point, normal = _vector(query.point, "point"), _vector(query.normal, "normal")
    length = np.linalg.norm(normal)
    if length < 1e-9:
        raise SceneSuggestError("the normal must not be zero", field="normal")
    normal = normal / length
    lo, hi = parent.world_bbox()
    distance = float(np.linalg.norm(np.maximum(0, np.maximum(lo - point, point - hi))))
    if distance > max(POINT_TOLERANCE_M, 0.05 * float(np.linalg.norm(hi - lo))):
        raise SceneSuggestError(f"the point is {distance:.2f} m away from {parent.category} "
                                f"{parent.id!r}", field="point")
    if query.scene_type is not None:
        scene_type = query.scene_type
    elif infer:
        scene_type = infer_scene_type((o.category for o in scene), taxonomy)
    else:
        scene_type = scene.scene_type
    refs = [(parent, "parent")] + [(q, "sibling") for q in scene.children(parent.id)]
    return Prepared(query, point, normal, surfaces.surface_type(parent.transform, parent.size, point, normal),
                    scene_type, parent.category, refs, wall_reference(scene, point, normal))


def _vector(value, name: str) -> np.ndarray:
    try:
        v = np.asarray(value, dtype=float).reshape(-1)
    except (TypeError, ValueError, OverflowError):  # an integer too large for a float among them, too
        raise SceneSuggestError("expected three numbers", field=name) from None
    if v.shape != (3,) or not np.all(np.isfinite(v)):
        raise SceneSuggestError("expected three finite numbers", field=name)
    return v
