"""The scene model: object instances in the world frame and their support tree.

Units and frames follow :mod:`scenesuggest.scenes.frames`: metres, +Y up; ``transform`` maps an object's
canonical model frame (bbox bottom centred at the origin, +Z front) to the world.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass, field, replace

import numpy as np

from ..errors import SceneSuggestError
from . import frames

#: Surface directions and sides; a contact's surface type is ``f"{direction}_{side}"``.
SURFACE_DIRECTIONS = ("up", "down", "vertical")
SURFACE_SIDES = ("interior", "exterior")
SURFACE_TYPES = tuple(f"{d}_{s}" for d in SURFACE_DIRECTIONS for s in SURFACE_SIDES)

#: The category of room shells (the root of every support tree).
ROOM = "Room"
#: The category of a model no label names (a corpus's bookkeeping, not a thing anyone places).
UNKNOWN = "Unknown"
#: Categories no one can want: a corpus's bookkeeping (never suggested, never mapped between corpora).
PLACEHOLDERS = frozenset({ROOM, UNKNOWN})


@dataclass
class ObjectInstance:
    """One object of a scene.

    ``size`` is the model's bbox extent (x, y, z) in metres in its canonical frame. For a supported
    object, ``parent`` is the id of its support parent, ``surface_type`` the parent's surface at the
    contact, ``attachment_face`` the face of this object's bbox that touches it, and
    ``contact_point`` / ``contact_normal`` the world contact point and the parent's surface normal there.
    """

    id: str
    model_id: str
    category: str
    transform: np.ndarray
    size: tuple[float, float, float]
    parent: str | None = None
    surface_type: str | None = None
    attachment_face: str | None = None
    contact_point: tuple[float, float, float] | None = None
    contact_normal: tuple[float, float, float] | None = None

    def world_bbox(self) -> tuple[np.ndarray, np.ndarray]:
        return frames.world_bbox(self.transform, self.size)

    def centre(self) -> np.ndarray:
        """The world centre of the object's box."""
        lo, hi = self.world_bbox()
        return (lo + hi) / 2

    def scaled_size(self) -> np.ndarray:
        """The box's extent (x, y, z) in metres as the scene places it (``size`` times the transform's scale)."""
        return np.asarray(self.size, dtype=float) * np.linalg.norm(self.transform[:3, :3], axis=0)

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, ObjectInstance):
            return NotImplemented
        return (
            self.id == other.id and self.model_id == other.model_id and self.category == other.category
            and np.array_equal(self.transform, other.transform) and tuple(self.size) == tuple(other.size)
            and self.parent == other.parent and self.surface_type == other.surface_type
            and self.attachment_face == other.attachment_face
            and self.contact_point == other.contact_point and self.contact_normal == other.contact_normal
        )


@dataclass
class Scene:
    """A scene: its type and its objects, keyed by id in file order. ``walls``: the room's walls when known
    (:class:`scenesuggest.scenes.walls.Wall`; None: take them from the room object's box). ``type_from_objects``:
    the type was inferred from the scene's own objects (Stanford's, RoboTHOR's), not declared apart from them (a
    room group's, a scene file's) — a held-out query infers it again without the object asked about."""

    id: str
    scene_type: str
    objects: dict[str, ObjectInstance] = field(default_factory=dict)
    source: str = ""
    walls: list | None = None
    type_from_objects: bool = False

    def __iter__(self) -> Iterator[ObjectInstance]:
        return iter(self.objects.values())

    def __len__(self) -> int:
        return len(self.objects)

    def children(self, object_id: str | None) -> list[ObjectInstance]:
        """Objects supported directly by ``object_id`` (``None``: the roots)."""
        return [o for o in self.objects.values() if o.parent == object_id]

    def roots(self) -> list[ObjectInstance]:
        return self.children(None)

    def descendants(self, object_id: str) -> list[ObjectInstance]:
        """Everything resting on ``object_id``, directly or indirectly (not the object itself)."""
        out, stack = [], [object_id]
        while stack:
            for child in self.children(stack.pop()):
                out.append(child)
                stack.append(child.id)
        return out

    def without(self, object_id: str) -> Scene:
        """A copy of the scene with ``object_id`` and everything it supports removed."""
        gone = {object_id} | {o.id for o in self.descendants(object_id)}
        kept = {k: v for k, v in self.objects.items() if k not in gone}
        return replace(self, objects=kept)

    def validate(self, file: str | None = None, lines: dict[str, int] | None = None) -> None:
        """Check the support tree: every parent exists, no object supports itself, no cycles.

        ``lines`` maps object ids to the line where each is defined, for error messages.
        """
        lines = lines or {}
        for o in self.objects.values():
            if o.parent is not None and o.parent not in self.objects:
                raise SceneSuggestError(f"object {o.id!r} names parent {o.parent!r}, which is not in the scene",
                                        file=file, line=lines.get(o.id), field="parent")
        state: dict[str, int] = {}  # 1 = on the current path, 2 = done
        for start in self.objects:
            path = []
            node: str | None = start
            while node is not None and state.get(node) != 2:
                if state.get(node) == 1:
                    cycle = path[path.index(node):] + [node]
                    raise SceneSuggestError("cycle in the support tree: " + " -> ".join(cycle),
                                            file=file, line=lines.get(node), field="parent")
                state[node] = 1
                path.append(node)
                node = self.objects[node].parent
            for n in path:
                state[n] = 2
