"""Support surfaces of models and ray casting against scenes."""

import math

import numpy as np
import pytest
import trimesh

from scenesuggest import frames
from scenesuggest.assets.convert import convert_model
from scenesuggest.assets.procedural import procedural_model
from scenesuggest.geometry import SceneRaycaster, support_surfaces
from scenesuggest.scene import ObjectInstance, Scene


def test_support_surfaces_of_a_shelving_unit():
    """Four boards: the top one is the outside of the unit, the three below are inside it."""
    unit = procedural_model("ShelvingUnit", (0.9, 1.8, 0.4))
    found = support_surfaces(unit)
    boards = sorted((s for s in found if s.area > 0.2), key=lambda s: s.height)
    assert len(boards) == 4
    assert [s.side for s in boards] == ["interior"] * 3 + ["exterior"]
    assert boards[-1].height == pytest.approx(1.8, abs=1e-6)
    assert boards[0].area == pytest.approx(0.9 * 0.92 * 0.4 * 0.97, rel=0.05)


def test_support_surfaces_of_a_real_desk_skip_duplicate_faces(stanford, tmp_path):
    info = stanford.models["569e2fce2f1ab3be617e9d9aa36a8137"]
    desk = convert_model(info, info.mesh, tmp_path / "desk.glb")
    found = support_surfaces(desk)
    top = found[0]
    assert top.height == pytest.approx(info.size[1], abs=0.01) and top.side == "exterior"
    assert top.area == pytest.approx(info.size[0] * info.size[2], rel=0.1)
    keys = [(round(s.height, 3), s.footprint_min, s.footprint_max) for s in found]
    assert len(keys) == len(set(keys))


def desk_scene() -> Scene:
    s = Scene("t", "Study")
    s.objects["room"] = ObjectInstance("room", "room", "Room", frames.scaling([4.0, 2.5, 4.0]), (1.0, 1.0, 1.0))
    desk_t = frames.translation([0.5, 0, -1.0]) @ frames.rotation_y(math.radians(90))
    s.objects["desk"] = ObjectInstance("desk", "d", "Desk", desk_t, (1.2, 0.75, 0.6), parent="room")
    s.objects["shelf"] = ObjectInstance("shelf", "b", "Bookcase", frames.translation([-1.5, 0, 1.5]),
                                        (0.8, 1.8, 0.3), parent="room")
    return s


def test_ray_hits_are_classified():
    scene = desk_scene()
    shelves = procedural_model("ShelvingUnit", (0.8, 1.8, 0.3))
    cast = SceneRaycaster(scene, meshes=lambda o: shelves if o.id == "shelf" else None)
    top = cast.cast_one([0.5, 2.0, -1.0], [0, -1, 0])
    assert top.object_id == "desk" and top.surface_type == "up_exterior"
    assert top.point == pytest.approx((0.5, 0.75, -1.0)) and top.normal == pytest.approx((0, 1, 0))
    floor = cast.cast_one([1.5, 2.0, 1.0], [0, -1, 0])
    assert floor.object_id == "room" and floor.surface_type == "up_interior"
    wall = cast.cast_one([0, 1.2, 0], [1, 0, 0])
    assert wall.object_id == "room" and wall.surface_type == "vertical_interior"
    assert wall.normal == pytest.approx((-1, 0, 0))
    # into the shelving unit from the front, just above its second board: an interior shelf
    board = cast.cast_one([-1.5, 0.9, 1.95], [0, -0.45, -1])
    assert board.object_id == "shelf" and board.surface_type == "up_interior"
    assert cast.cast_one([0, 1, 0], [0, 1, 0]).surface_type == "down_interior"  # the ceiling


def test_many_rays_at_once():
    cast = SceneRaycaster(desk_scene())
    rng = np.random.default_rng(0)
    origins = rng.uniform([-1.5, 0.1, -1.5], [1.5, 2.0, 1.5], (500, 3))
    hits = cast.cast(origins, rng.normal(size=(500, 3)))
    assert all(h is not None for h in hits)  # inside a closed room every ray hits something
    assert {h.object_id for h in hits} >= {"room", "desk"}
    assert all(np.dot(h.normal, np.subtract(o, h.point)) > 0 for h, o in zip(hits, origins, strict=True))


def test_a_ray_that_misses():
    s = Scene("t", "Room")
    s.objects["a"] = ObjectInstance("a", "m", "Box", frames.translation([0, 0, 0]), (1.0, 1.0, 1.0))
    assert SceneRaycaster(s).cast_one([5, 0.5, 0], [1, 0, 0]) is None
    hit = SceneRaycaster(s, meshes=lambda o: trimesh.creation.icosphere()).cast_one([5, 0, 0], [-1, 0, 0])
    assert hit.distance == pytest.approx(4.0, abs=0.01)
