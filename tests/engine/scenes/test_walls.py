"""Walls as references: from a room box, from a room mesh, in the native format, and which one is nearest."""

import numpy as np
import pytest
import trimesh

from scenesuggest.errors import SceneSuggestError
from scenesuggest.scenes import scene_json
from scenesuggest.scenes.walls import Wall, box_walls, mesh_walls, nearest_wall, room_walls


def test_box_walls_face_into_the_room_and_the_nearest_one_is_found():
    walls = box_walls((-2.5, 0.0, -2.0), (2.5, 2.7, 2.0))
    normals = sorted(w.normal for w in walls)
    assert normals == [(-1.0, 0.0), (0.0, -1.0), (0.0, 1.0), (1.0, 0.0)]
    wall, distance = nearest_wall(walls, (0.3, 0.0, -1.6))  # 0.4 m in front of the back wall
    assert wall.normal == (0.0, 1.0) and distance == pytest.approx(0.4)
    wall, distance = nearest_wall(walls, (-2.2, 0.0, 1.0))
    assert wall.normal == (1.0, 0.0) and distance == pytest.approx(0.3)
    assert nearest_wall(walls, (0.0, 0.0, -3.0))[0].normal != (0.0, 1.0)  # behind the back wall: not in front of it
    assert nearest_wall([], (0, 0, 0)) is None


def test_walls_of_a_room_mesh_are_its_large_vertical_planes_that_reach_the_floor():
    # an open box (floor and four walls) plus a window reveal that does not reach the floor
    room = trimesh.creation.box((6.0, 3.0, 5.0))
    room.apply_translation((3.0, 1.5, -2.5))
    room.invert()  # faces point inwards, as a room's do
    reveal = trimesh.creation.box((0.1, 1.0, 1.0))
    reveal.apply_translation((2.0, 1.5, -4.9))
    mesh = trimesh.util.concatenate([room, reveal])
    walls = mesh_walls(mesh.vertices, mesh.faces)
    assert len(walls) == 4
    back = [w for w in walls if w.normal == pytest.approx((0.0, 1.0))]
    assert back and back[0].offset == pytest.approx(-5.0) and back[0].height == pytest.approx((0.0, 3.0))
    wall, distance = nearest_wall(walls, (3.0, 0.0, -4.5))
    assert wall.normal == pytest.approx((0.0, 1.0)) and distance == pytest.approx(0.5)


def test_scenes_carry_walls_through_the_native_format(tmp_path):
    import synthetic

    scene = synthetic.corpus().scenes[0]
    assert room_walls(scene) == box_walls(*scene.objects["room"].world_bbox())
    scene.walls = [Wall((0.0, 1.0), -2.0, (-2.5, 2.5), (0.0, 2.7))]
    again = scene_json.loads(scene_json.dumps(scene))
    assert again.walls == scene.walls and again.without("room").walls == scene.walls
    doc = scene_json.scene_to_dict(scene)
    doc["walls"][0]["normal"] = [0.0, 2.0]
    with pytest.raises(SceneSuggestError) as info:
        scene_json.from_dict(doc)
    assert info.value.field == "normal"
    doc["walls"][0] = {"normal": [0.0, 1.0], "offset": -2.0, "along": [2.5, -2.5], "height": [0, 1]}
    with pytest.raises(SceneSuggestError) as info:
        scene_json.from_dict(doc)
    assert info.value.field == "along"
    for wall, field in (({"normal": [0.0, 1.0], "offset": "far", "along": [0, 1], "height": [0, 1]}, "offset"),
                        ({"normal": [0.0, 1.0], "offset": float("nan"), "along": [0, 1], "height": [0, 1]}, "offset"),
                        ({"normal": [0.0, 1.0], "offset": True, "along": [0, 1], "height": [0, 1]}, "offset"),
                        ({"normal": [0.0, 1.0], "offset": 0, "along": [0, 1], "height": [0, 1], "x": 1}, "x"),
                        ({"normal": [0.0, 1.0], "offset": 0, "along": [0, 1]}, "height"),
                        ("wall", "walls")):
        doc["walls"] = [wall]
        with pytest.raises(SceneSuggestError) as info:
            scene_json.from_dict(doc)
        assert info.value.field == field


def test_stanford_rooms_have_the_walls_of_their_meshes(stanford):
    with_walls = [s for s in stanford.scenes if s.walls]
    assert len(with_walls) == len(stanford.scenes)
    # every object hung on a wall of its room is in front of one of the measured walls, within a few cm
    gaps = []
    for s in stanford.scenes:
        for o in s:
            if o.parent in s.objects and s.objects[o.parent].parent is None and o.surface_type == "vertical_interior":
                found = nearest_wall(s.walls, o.contact_point)
                gaps.append(found[1] if found else np.inf)
    assert len(gaps) > 100 and np.mean(np.array(gaps) < 0.1) > 0.9
