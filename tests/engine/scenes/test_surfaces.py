import math

import pytest

from scenesuggest.scenes import frames
from scenesuggest.scenes.surfaces import attachment_face, surface_direction, surface_type

ROOM = frames.translation([0, 0, 0]) @ frames.scaling([5.0, 2.6, 4.0])  # unit room model scaled
DESK = frames.translation([1.0, 0.0, -1.5]) @ frames.rotation_y(math.radians(30))
DESK_SIZE = (1.2, 0.75, 0.6)
BOOKCASE = frames.translation([-2.0, 0.0, 1.8]) @ frames.rotation_y(math.pi)
BOOKCASE_SIZE = (0.9, 2.0, 0.35)


@pytest.mark.parametrize(("normal", "expected"), [
    ((0, 1, 0), "up"), ((0, -1, 0), "down"), ((1, 0, 0), "vertical"),
    ((0.5, 0.8, 0), "up"), ((0.8, 0.5, 0), "vertical"),
])
def test_surface_direction(normal, expected):
    assert surface_direction(normal) == expected


def test_room_floor_and_walls_are_interior():
    assert surface_type(ROOM, (1, 1, 1), (0.3, 0.0, 0.2), (0, 1, 0)) == "up_interior"
    assert surface_type(ROOM, (1, 1, 1), (-2.5, 1.4, 0.2), (1, 0, 0)) == "vertical_interior"
    assert surface_type(ROOM, (1, 1, 1), (0.0, 1.4, 2.0), (0, 0, -1)) == "vertical_interior"


def test_desk_top_is_exterior_and_underside_interior():
    top = frames.apply(DESK, [[0.2, 0.75, 0.1]])[0]
    assert surface_type(DESK, DESK_SIZE, top, (0, 1, 0)) == "up_exterior"
    under = frames.apply(DESK, [[0.2, 0.72, 0.1]])[0]
    assert surface_type(DESK, DESK_SIZE, under, (0, -1, 0)) == "down_interior"
    side = frames.apply(DESK, [[0.6, 0.4, 0.0]])[0]
    assert surface_type(DESK, DESK_SIZE, side, frames.rotation_y(math.radians(30))[:3, 0]) == "vertical_exterior"


def test_shelf_inside_bookcase_is_interior_but_its_top_is_exterior():
    shelf = frames.apply(BOOKCASE, [[0.0, 1.1, 0.0]])[0]
    assert surface_type(BOOKCASE, BOOKCASE_SIZE, shelf, (0, 1, 0)) == "up_interior"
    top = frames.apply(BOOKCASE, [[0.0, 2.0, 0.0]])[0]
    assert surface_type(BOOKCASE, BOOKCASE_SIZE, top, (0, 1, 0)) == "up_exterior"


def test_attachment_face_follows_the_childs_own_axes():
    poster = frames.translation([-2.5, 1.5, 0]) @ frames.rotation_y(math.pi / 2)  # front faces +x, into the room
    assert attachment_face(poster, (1, 0, 0)) == "back"
    lamp = frames.translation([0, 0.75, 0]) @ frames.rotation_y(1.0) @ frames.scaling(3.0)
    assert attachment_face(lamp, (0, 1, 0)) == "bottom"
    ceiling_lamp = frames.translation([0, 2.6, 0])
    assert attachment_face(ceiling_lamp, (0, -1, 0)) == "top"
    sideways = frames.translation([0, 1, 0]) @ frames.rotation_y(-math.pi / 2)  # front faces -x; left side +z
    assert attachment_face(sideways, (0, 0, -1)) == "left"
