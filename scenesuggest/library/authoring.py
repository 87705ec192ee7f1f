"""Target scenes composed in code: a box room, objects stood on surfaces and hung on walls.

World frame as everywhere: metres, +Y up; the room box is centred on the origin in X and Z with its floor at
y = 0. Walls are named by the side they bound: ``back`` (z = −depth/2, facing +Z), ``front`` (z = +depth/2),
``left`` (x = −width/2, facing +X) and ``right`` (x = +width/2). A heading (yaw) of 0° faces an object's
front (+Z of its canonical frame) along world +Z; positive yaws turn it counter-clockwise seen from above.
"""

from __future__ import annotations

import math

import numpy as np

from ..errors import SceneSuggestError
from ..scenes import frames, poses, surfaces
from ..scenes.scene import ObjectInstance, Scene
from .index import ModelInfo

WALLS = {  # wall → (inward normal, axis along the wall, which room extent gives its offset)
    "back": ((0.0, 0.0, 1.0), 0),
    "front": ((0.0, 0.0, -1.0), 0),
    "left": ((1.0, 0.0, 0.0), 2),
    "right": ((-1.0, 0.0, 0.0), 2),
}


class SceneAuthor:
    """Compose a scene from a library of models, one model per category (``models``: category → model)."""

    def __init__(self, scene_id: str, scene_type: str, models: dict[str, ModelInfo],
                 room: tuple[float, float, float] = (5.0, 2.7, 4.0), source: str = "authored",
                 room_model: str = "room"):
        self.models = models
        self.room = tuple(float(v) for v in room)
        self.scene = Scene(scene_id, scene_type, source=source)
        self.scene.objects["room"] = ObjectInstance("room", room_model, "Room", frames.scaling(self.room),
                                                    (1.0, 1.0, 1.0))

    def model(self, category: str) -> ModelInfo:
        try:
            return self.models[category]
        except KeyError:
            raise SceneSuggestError(f"no model of category {category!r} in the library", field="category") from None

    def size(self, category: str) -> tuple[float, float, float]:
        """A model's bounding-box size (metres) in its canonical frame: width X, height Y, depth Z."""
        return tuple(self.model(category).size)

    def top(self, object_id: str) -> float:
        """Height of the top of an object's world box (metres)."""
        return float(self.scene.objects[object_id].world_bbox()[1][1])

    def wall_position(self, wall: str) -> float:
        normal, along = WALLS[wall]
        half = self.room[2 - along] / 2  # back/front walls sit at ±depth/2, left/right at ±width/2
        return -half if sum(normal) > 0 else half

    def put(self, category: str, parent: str, x: float, z: float, yaw_deg: float = 0.0) -> str:
        """Stand ``category`` on top of ``parent`` (``"room"``: the floor) at world (x, z), heading ``yaw_deg``."""
        height = 0.0 if parent == "room" else self.top(parent)
        point, normal, face = np.array([x, height, z]), np.array([0.0, 1.0, 0.0]), "bottom"
        alpha = math.radians(yaw_deg) - poses.zero_heading(face, normal)
        return self._add(category, parent, point, normal, face, alpha)

    def hang(self, category: str, wall: str, along: float, y: float) -> str:
        """Hang ``category`` by its back on ``wall``, its back centre at ``along`` metres along the wall (X for
        back/front walls, Z for left/right) and ``y`` metres above the floor, upright."""
        if wall not in WALLS:
            raise SceneSuggestError(f"unknown wall {wall!r}; expected one of {', '.join(WALLS)}", field="wall")
        normal, axis = WALLS[wall]
        point = np.zeros(3)
        point[axis] = along
        point[1] = y
        point[2 - axis] = self.wall_position(wall)
        return self._add(category, "room", point, np.array(normal), "back", 0.0)

    def _add(self, category, parent, point, normal, face, alpha) -> str:
        model = self.model(category)
        t = poses.placement(point, normal, face, model.size, alpha)
        p = self.scene.objects[parent]
        oid = f"{category.lower()}-{len(self.scene.objects)}"
        self.scene.objects[oid] = ObjectInstance(
            oid, model.id, model.category, t, tuple(float(v) for v in model.size), parent=parent,
            surface_type=surfaces.surface_type(p.transform, p.size, point, normal), attachment_face=face,
            contact_point=tuple(float(v) for v in point), contact_normal=tuple(float(v) for v in normal))
        return oid
