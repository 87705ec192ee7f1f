"""Small hand-made corpora with known statistics, for exact tests of the priors and the engine.

Study: a 5 m × 4 m room; a desk against the back wall (front +Z); on the desk a monitor 20 cm behind the
centre facing front, a keyboard 15 cm in front, two speakers 40 cm either side; an office chair 70 cm in
front of the desk facing it; a poster on the back wall at 1.8 m and a power socket at 0.3 m.
Bedroom: a bed against the back wall, a nightstand beside it carrying a lamp and (in every other scene) a
book. Positions are jittered by a seeded generator so that densities have some width.
"""

from __future__ import annotations

import math

import numpy as np

from scenesuggest.corpora.corpus import Corpus
from scenesuggest.scenes import frames, surfaces
from scenesuggest.scenes.scene import ObjectInstance, Scene
from scenesuggest.scenes.taxonomy import Taxonomy

SIZES = {
    "Room": (1.0, 1.0, 1.0), "Desk": (1.4, 0.75, 0.7), "Monitor": (0.55, 0.45, 0.2), "Keyboard": (0.45, 0.03, 0.15),
    "Speaker": (0.12, 0.2, 0.12), "OfficeChair": (0.6, 1.0, 0.6), "Poster": (0.6, 0.8, 0.01),
    "PowerSocket": (0.08, 0.08, 0.03), "Bed": (1.6, 0.6, 2.1), "Nightstand": (0.5, 0.55, 0.4),
    "DeskLamp": (0.25, 0.45, 0.25), "Book": (0.2, 0.04, 0.28), "Couch": (2.2, 0.85, 0.9),
}
TAXONOMY = Taxonomy({"OfficeChair": "Chair", "Monitor": "Electronics", "Keyboard": "Electronics",
                     "Speaker": "Electronics", "Nightstand": "Table", "Desk": "Table", "Poster": "WallArt"})
ROOM_SIZE = (5.0, 2.7, 4.0)  # x, height, z; the back wall is at z = -2, facing +Z


class Builder:
    def __init__(self, scene_id: str, scene_type: str):
        self.scene = Scene(scene_id, scene_type, type_from_objects=True)  # the type its furniture implies, as
        # Stanford's: a held-out query infers it again without the object asked about
        room = ObjectInstance("room", "m:Room", "Room", frames.scaling(ROOM_SIZE), (1.0, 1.0, 1.0))
        self.scene.objects["room"] = room

    def add(self, category: str, parent: str, point, normal=(0.0, 1.0, 0.0), yaw_deg: float = 0.0,
            face: str | None = None) -> str:
        """Place ``category`` with its attachment face centred at ``point`` on ``parent``."""
        from scenesuggest.scenes import poses

        size = SIZES[category]
        n = np.asarray(normal, dtype=float)
        face = face or ("bottom" if n[1] > 0.5 else "back")
        zero = poses.zero_heading(face, n)
        alpha = math.radians(yaw_deg) - (0.0 if math.isnan(zero) else zero) if n[1] > 0.5 else 0.0
        t = poses.placement(point, n, face, size, alpha)
        p = self.scene.objects[parent]
        oid = f"{category.lower()}{len(self.scene.objects)}"
        self.scene.objects[oid] = ObjectInstance(
            oid, f"m:{category}", category, t, size, parent=parent,
            surface_type=surfaces.surface_type(p.transform, p.size, point, n), attachment_face=face,
            contact_point=tuple(float(v) for v in point), contact_normal=tuple(float(v) for v in n))
        return oid


def study(i: int, rng: np.random.Generator) -> Scene:
    b = Builder(f"study{i:02d}", "Study")
    dx = rng.uniform(-1.0, 1.0)
    desk_z = -2.0 + 0.35
    desk = b.add("Desk", "room", (dx, 0.0, desk_z))
    top = 0.75
    j = lambda s=0.02: rng.normal(0, s)  # noqa: E731
    b.add("Monitor", desk, (dx + j(), top, desk_z - 0.2 + j()), yaw_deg=j(3))
    b.add("Keyboard", desk, (dx + j(), top, desk_z + 0.15 + j()), yaw_deg=j(3))
    b.add("Speaker", desk, (dx - 0.4 + j(), top, desk_z - 0.15 + j()), yaw_deg=j(5))
    b.add("Speaker", desk, (dx + 0.4 + j(), top, desk_z - 0.15 + j()), yaw_deg=j(5))
    b.add("OfficeChair", "room", (dx + j(0.05), 0.0, desk_z + 0.7 + j(0.05)), yaw_deg=180 + j(5))
    b.add("Poster", "room", (dx + j(0.1), 1.8 + j(0.05), -2.0), normal=(0, 0, 1))
    b.add("PowerSocket", "room", (dx + 0.6 + j(0.1), 0.3 + j(0.02), -2.0), normal=(0, 0, 1))
    return b.scene


def bedroom(i: int, rng: np.random.Generator) -> Scene:
    b = Builder(f"bedroom{i:02d}", "Bedroom")
    bx = rng.uniform(-1.0, 1.0)
    b.add("Bed", "room", (bx, 0.0, -2.0 + 1.05))
    stand = b.add("Nightstand", "room", (bx + 1.2, 0.0, -2.0 + 0.2 + rng.normal(0, 0.02)))
    b.add("DeskLamp", stand, (bx + 1.2 + rng.normal(0, 0.02), 0.55, -1.85))
    if i % 2 == 0:
        b.add("Book", stand, (bx + 1.15 + rng.normal(0, 0.02), 0.55, -1.7), yaw_deg=rng.normal(0, 10))
    return b.scene


def corpus(n_study: int = 12, n_bedroom: int = 8, seed: int = 0) -> Corpus:
    rng = np.random.default_rng(seed)
    scenes = [study(i, rng) for i in range(n_study)] + [bedroom(i, rng) for i in range(n_bedroom)]
    return Corpus("synthetic", scenes, {}, TAXONOMY)
