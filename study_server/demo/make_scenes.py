"""Author the demo study's target scenes from the built-in (AI2-THOR type) model library.

Each scene is a 5 m × 2.7 m × 4 m room (back wall at z = −2, facing +Z) with a few objects placed by hand
here; sizes are the library's typical sizes. Run it to regenerate ``scenes/*.json``:

    .venv/bin/python study_server/demo/make_scenes.py
"""

from __future__ import annotations

from pathlib import Path

from scenesuggest.corpora import load_corpus
from scenesuggest.library.authoring import SceneAuthor
from scenesuggest.scenes import scene_json
from scenesuggest.scenes.scene import Scene

HERE = Path(__file__).resolve().parent
ROOM = (5.0, 2.7, 4.0)
BACK = -ROOM[2] / 2


def author(scene_id: str, scene_type: str, models) -> SceneAuthor:
    return SceneAuthor(scene_id, scene_type, models, ROOM, source="authored: study_server/demo/make_scenes.py",
                       room_model="ai2thor:Room")


def depth(models, category) -> float:
    return models[category].size[2]


def scenes(models) -> list[Scene]:
    out = []

    a = author("practice", "Kitchen", models)
    table = a.put("DiningTable", "room", 0.0, 0.0)
    a.put("Plate", table, -0.2, 0.1)
    a.put("Apple", table, 0.25, -0.1)
    a.put("Bowl", table, 0.0, -0.25)
    out.append(a.scene)

    a = author("desk-corner", "Study", models)
    desk = a.put("Desk", "room", 0.0, BACK + depth(models, "Desk") / 2)
    a.put("Laptop", desk, 0.0, BACK + 0.35, yaw_deg=0)
    a.put("DeskLamp", desk, -0.45, BACK + 0.2)
    a.put("Mug", desk, 0.4, BACK + 0.4, yaw_deg=30)
    a.put("Book", desk, -0.35, BACK + 0.45, yaw_deg=-15)
    a.put("Chair", "room", 0.0, BACK + depth(models, "Desk") + 0.45, yaw_deg=180)
    a.hang("Painting", "back", 0.0, 1.65)
    out.append(a.scene)

    a = author("bedside", "Bedroom", models)
    a.put("Bed", "room", -0.4, BACK + depth(models, "Bed") / 2)
    stand = a.put("SideTable", "room", -0.4 + models["Bed"].size[0] / 2 + 0.35, BACK + depth(models, "SideTable") / 2)
    sx = -0.4 + models["Bed"].size[0] / 2 + 0.35
    a.put("DeskLamp", stand, sx - 0.08, BACK + 0.15)
    a.put("AlarmClock", stand, sx + 0.1, BACK + 0.25, yaw_deg=-20)
    a.put("Book", stand, sx - 0.05, BACK + 0.35, yaw_deg=10)
    a.hang("Painting", "back", -0.4, 1.5)
    out.append(a.scene)

    a = author("sofa-corner", "LivingRoom", models)
    a.put("Sofa", "room", 0.0, BACK + depth(models, "Sofa") / 2)
    coffee = a.put("CoffeeTable", "room", 0.0, BACK + depth(models, "Sofa") + 0.55)
    cz = BACK + depth(models, "Sofa") + 0.55
    a.put("Vase", coffee, -0.15, cz - 0.05)
    a.put("RemoteControl", coffee, 0.15, cz + 0.1, yaw_deg=80)
    a.put("FloorLamp", "room", models["Sofa"].size[0] / 2 + 0.35, BACK + 0.35)
    a.put("HousePlant", "room", -models["Sofa"].size[0] / 2 - 0.4, BACK + 0.35)
    out.append(a.scene)
    return out


def main() -> None:
    models = {m.category: m for m in load_corpus("ai2thor").models.values()}
    (HERE / "scenes").mkdir(exist_ok=True)
    for scene in scenes(models):
        scene_json.save(scene, HERE / "scenes" / f"{scene.id}.json")
        print(f"wrote scenes/{scene.id}.json ({len(scene) - 1} objects)")


if __name__ == "__main__":
    main()
