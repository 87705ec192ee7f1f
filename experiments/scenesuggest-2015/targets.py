"""The replication's target scenes, composed from the study's representative models.

Each target recreates the gist of one scene of the Stanford corpus (its *source*, held out of prior training)
with 5–10 representative models, as the paper's targets were: a desk, a computer desk with a wall socket and
a poster, a bedroom corner, a living-room corner, a dining table and a bookshelf. The layouts are ours; only
the categories follow the source scenes. Four need wall objects; four need an object turned away from its
canonical heading (a chair facing its desk, a couch along a side wall, dining chairs round their table).

World frame (metres, +Y up), a 5 m × 2.7 m × 4 m room centred on the origin; the back wall is at z = −2.
Categories are those of the representatives file (first column); the scene records each model's own category.
"""

from __future__ import annotations

from collections.abc import Callable

from scenesuggest.library.authoring import SceneAuthor
from scenesuggest.scenes.scene import Scene
from scenesuggest.scenes.scene_types import infer_scene_type
from study_server.studies.new_study import side_table  # the practice scene of every new Stanford study

ROOM = (5.0, 2.7, 4.0)
BACK = -ROOM[2] / 2
LEFT = -ROOM[0] / 2

# target id → (title, held-out source scene of the Stanford corpus)
TARGETS = {
    "practice": ("Practice: a side table", None),
    "desk": ("A desk", "scene00117"),
    "computer-desk": ("A computer desk", "scene00030"),
    "bedroom-corner": ("A bedroom corner", "scene00057"),
    "living-corner": ("A living-room corner", "scene00060"),
    "dining-table": ("A dining table", "scene00046"),
    "bookshelf": ("A bookshelf", "scene00014"),
}
PERIODS = (("desk", "computer-desk", "bedroom-corner"), ("living-corner", "dining-table", "bookshelf"))


def held_out() -> list[str]:
    """Source scenes of the targets: left out when the study's priors are trained."""
    return sorted(source for _, source in TARGETS.values() if source)




def _desk(a: SceneAuthor) -> None:
    desk = a.put("Desk", "room", 0.0, BACK + a.size("Desk")[2] / 2)
    a.put("DeskLamp", desk, -0.62, BACK + 0.35)
    a.put("StackBooks", desk, -0.15, BACK + 0.25, yaw_deg=-10)
    a.put("Notepad", desk, 0.2, BACK + 0.6, yaw_deg=15)
    a.put("Pencil", desk, 0.45, BACK + 0.72, yaw_deg=60)
    a.put("Stapler", desk, 0.5, BACK + 0.25, yaw_deg=20)
    a.put("Mug", desk, 0.62, BACK + 0.55)
    a.put("TrashBin", "room", 1.15, BACK + 0.3)


def _computer_desk(a: SceneAuthor) -> None:
    d = a.size("Desk")[2]
    desk = a.put("Desk", "room", 0.0, BACK + d / 2)
    a.put("Monitor", desk, 0.0, BACK + 0.2)
    a.put("Keyboard", desk, 0.0, BACK + 0.55)
    a.put("ComputerMouse", desk, 0.4, BACK + 0.55, yaw_deg=180)  # the model's front is its cable end
    a.put("Speaker", desk, -0.55, BACK + 0.25, yaw_deg=15)
    a.put("OfficeChair", "room", 0.0, BACK + d + 0.45, yaw_deg=180)
    a.hang("PowerSocket", "back", 1.25, 0.3)
    a.hang("Poster", "back", 0.0, 1.8)


def _bedroom_corner(a: SceneAuthor) -> None:
    w, _, d = a.size("Dresser")
    x = LEFT + 0.25 + w / 2
    dresser = a.put("Dresser", "room", x, BACK + d / 2)
    a.hang("Mirror", "back", x, 2.0)
    a.put("Candle", dresser, x - 0.3, BACK + 0.3)
    a.put("PictureFrame", dresser, x + 0.22, BACK + 0.2, yaw_deg=-20)
    a.put("Clock", dresser, x + 0.2, BACK + 0.7, yaw_deg=10)
    a.put("Vase", dresser, x - 0.2, BACK + 0.75)
    a.put("Basket", "room", x + w / 2 + 0.5, BACK + 0.4)


def _living_corner(a: SceneAuthor) -> None:
    _, _, d = a.size("Couch")
    cx, cz = LEFT + d / 2, -0.3
    a.put("Couch", "room", cx, cz, yaw_deg=90)  # along the left wall, facing into the room
    table_x = LEFT + d + 0.45 + a.size("CoffeeTable")[2] / 2
    table = a.put("CoffeeTable", "room", table_x, cz, yaw_deg=90)
    a.put("wn:remote control", table, table_x + 0.15, cz + 0.3, yaw_deg=100)
    a.put("FruitBowl", table, table_x - 0.1, cz - 0.3)
    side = a.put("EndTable", "room", LEFT + 0.25, BACK + 0.34, yaw_deg=90)
    a.put("Vase", side, LEFT + 0.25, BACK + 0.34)
    a.put("FloorLamp", "room", LEFT + 0.25, cz + a.size("Couch")[0] / 2 + 0.3)
    a.hang("WallArt", "left", cz, 1.65)


def _dining_table(a: SceneAuthor) -> None:
    _, _, d = a.size("DiningTable")
    table = a.put("DiningTable", "room", 0.0, 0.0)
    z = d / 2 + 0.3
    for x in (-0.45, 0.45):
        a.put("SideChair", "room", x, -z, yaw_deg=0)  # facing the table
        a.put("SideChair", "room", x, z, yaw_deg=180)
    a.put("Plate", table, -0.45, -0.3)
    a.put("Plate", table, 0.45, 0.3)
    a.put("FruitBowl", table, 0.0, 0.0)


def _bookshelf(a: SceneAuthor) -> None:
    _, _, d = a.size("4Shelves")
    shelf = a.put("4Shelves", "room", 0.4, BACK + d / 2)
    a.put("StandBooks", shelf, 0.22, BACK + d / 2)
    a.put("ToyFigure", shelf, 0.62, BACK + d / 2, yaw_deg=-20)
    a.put("PottedPlant", "room", -0.4, BACK + 0.3)
    a.put("Chair", "room", 1.5, -0.9, yaw_deg=-135)
    a.hang("WallArt", "back", -1.4, 1.5)


COMPOSE: dict[str, Callable[[SceneAuthor], None]] = {
    "practice": side_table, "desk": _desk, "computer-desk": _computer_desk, "bedroom-corner": _bedroom_corner,
    "living-corner": _living_corner, "dining-table": _dining_table, "bookshelf": _bookshelf,
}


def compose(target_id: str, models: dict, taxonomy=None) -> Scene:
    """Target scene ``target_id`` from ``models`` (representatives file category → model)."""
    title, source = TARGETS[target_id]
    a = SceneAuthor(target_id, "Room", models, ROOM,
                    source=f"authored after Stanford {source}" if source else "authored")
    COMPOSE[target_id](a)
    a.scene.scene_type = infer_scene_type((o.category for o in a.scene), taxonomy)
    return a.scene
