"""Author the demo study's target scenes from the built-in (AI2-THOR type) model library.

Each scene is a 5 m × 2.7 m × 4 m room (back wall at z = −2, facing +Z) with a few objects placed by hand
here; sizes are the library's typical sizes. Run it to regenerate ``scenes/*.json``:

    .venv/bin/python experiments/demo/make_scenes.py
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from scenesuggest import frames, poses, scene_json, surfaces
from scenesuggest.corpora import load_corpus
from scenesuggest.scene import ObjectInstance, Scene

HERE = Path(__file__).resolve().parent
ROOM = (5.0, 2.7, 4.0)
BACK = -ROOM[2] / 2


class Author:
    def __init__(self, scene_id: str, scene_type: str, sizes: dict[str, tuple]):
        self.sizes = sizes
        self.scene = Scene(scene_id, scene_type, source="authored: experiments/demo/make_scenes.py")
        self.scene.objects["room"] = ObjectInstance("room", "ai2thor:Room", "Room", frames.scaling(ROOM),
                                                    (1.0, 1.0, 1.0))

    def top(self, object_id: str) -> float:
        return float(self.scene.objects[object_id].world_bbox()[1][1])

    def put(self, category: str, parent: str, x: float, z: float, yaw_deg: float = 0.0, y: float | None = None,
            wall: bool = False) -> str:
        """Stand ``category`` on ``parent`` at (x, z) facing ``yaw_deg`` (0 = +Z), or hang it on the back wall
        at height ``y``."""
        size = self.sizes[category]
        if wall:
            point, normal, face, alpha = np.array([x, y, BACK]), np.array([0.0, 0.0, 1.0]), "back", 0.0
        else:
            height = 0.0 if parent == "room" else self.top(parent)
            point, normal, face = np.array([x, height, z]), np.array([0.0, 1.0, 0.0]), "bottom"
            alpha = math.radians(yaw_deg) - poses.zero_heading(face, normal)
        t = poses.placement(point, normal, face, size, alpha)
        p = self.scene.objects[parent]
        oid = f"{category.lower()}-{len(self.scene.objects)}"
        self.scene.objects[oid] = ObjectInstance(
            oid, f"ai2thor:{category}", category, t, tuple(float(v) for v in size), parent=parent,
            surface_type=surfaces.surface_type(p.transform, p.size, point, normal), attachment_face=face,
            contact_point=tuple(float(v) for v in point), contact_normal=tuple(float(v) for v in normal))
        return oid


def depth(sizes, category) -> float:
    return sizes[category][2]


def scenes(sizes) -> list[Scene]:
    out = []

    a = Author("practice", "Kitchen", sizes)
    table = a.put("DiningTable", "room", 0.0, 0.0)
    a.put("Plate", table, -0.2, 0.1)
    a.put("Apple", table, 0.25, -0.1)
    a.put("Bowl", table, 0.0, -0.25)
    out.append(a.scene)

    a = Author("desk-corner", "Study", sizes)
    desk = a.put("Desk", "room", 0.0, BACK + depth(sizes, "Desk") / 2)
    a.put("Laptop", desk, 0.0, BACK + 0.35, yaw_deg=0)
    a.put("DeskLamp", desk, -0.45, BACK + 0.2)
    a.put("Mug", desk, 0.4, BACK + 0.4, yaw_deg=30)
    a.put("Book", desk, -0.35, BACK + 0.45, yaw_deg=-15)
    a.put("Chair", "room", 0.0, BACK + depth(sizes, "Desk") + 0.45, yaw_deg=180)
    a.put("Painting", "room", 0.0, 0.0, y=1.65, wall=True)
    out.append(a.scene)

    a = Author("bedside", "Bedroom", sizes)
    a.put("Bed", "room", -0.4, BACK + depth(sizes, "Bed") / 2)
    stand = a.put("SideTable", "room", -0.4 + sizes["Bed"][0] / 2 + 0.35, BACK + depth(sizes, "SideTable") / 2)
    sx = -0.4 + sizes["Bed"][0] / 2 + 0.35
    a.put("DeskLamp", stand, sx - 0.08, BACK + 0.15)
    a.put("AlarmClock", stand, sx + 0.1, BACK + 0.25, yaw_deg=-20)
    a.put("Book", stand, sx - 0.05, BACK + 0.35, yaw_deg=10)
    a.put("Painting", "room", -0.4, 0.0, y=1.5, wall=True)
    out.append(a.scene)

    a = Author("sofa-corner", "LivingRoom", sizes)
    a.put("Sofa", "room", 0.0, BACK + depth(sizes, "Sofa") / 2)
    coffee = a.put("CoffeeTable", "room", 0.0, BACK + depth(sizes, "Sofa") + 0.55)
    cz = BACK + depth(sizes, "Sofa") + 0.55
    a.put("Vase", coffee, -0.15, cz - 0.05)
    a.put("RemoteControl", coffee, 0.15, cz + 0.1, yaw_deg=80)
    a.put("FloorLamp", "room", sizes["Sofa"][0] / 2 + 0.35, BACK + 0.35)
    a.put("HousePlant", "room", -sizes["Sofa"][0] / 2 - 0.4, BACK + 0.35)
    out.append(a.scene)
    return out


def main() -> None:
    library = load_corpus("ai2thor").models
    sizes = {m.category: m.size for m in library.values()}
    (HERE / "scenes").mkdir(exist_ok=True)
    for scene in scenes(sizes):
        scene_json.save(scene, HERE / "scenes" / f"{scene.id}.json")
        print(f"wrote scenes/{scene.id}.json ({len(scene) - 1} objects)")


if __name__ == "__main__":
    main()
