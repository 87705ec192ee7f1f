import math

import numpy as np
import pytest

from scenesuggest.scenes import frames


def test_column_major_round_trip_puts_translation_in_elements_12_to_14():
    m = frames.translation([1.5, -2.0, 3.25]) @ frames.rotation_y(0.3)
    values = frames.to_column_major(m)
    assert values[12:15] == [1.5, -2.0, 3.25]
    assert np.array_equal(frames.from_column_major(values), m)


def test_from_column_major_rejects_wrong_length():
    with pytest.raises(ValueError, match="16 numbers"):
        frames.from_column_major([1.0] * 15)


def test_rotation_y_turns_front_towards_plus_x():
    front = frames.rotation_y(math.pi / 2)[:3, 2]
    assert np.allclose(front, [1, 0, 0])


def test_alignment_maps_stanford_default_up_and_front_to_canonical():
    r = frames.alignment((0, 0, 1), (0, -1, 0))
    assert np.allclose(r @ [0, 0, 1], [0, 1, 0])
    assert np.allclose(r @ [0, -1, 0], [0, 0, 1])
    assert np.isclose(np.linalg.det(r), 1.0)


def test_z_up_to_y_up_keeps_handedness():
    assert np.isclose(np.linalg.det(frames.Z_UP_TO_Y_UP), 1.0)
    assert np.allclose(frames.Z_UP_TO_Y_UP @ [0, 0, 1], [0, 1, 0])


@pytest.mark.parametrize("face", frames.FACES)
def test_face_of_direction_inverts_face_normals(face):
    assert frames.face_of_direction(frames.FACE_NORMALS[face]) == face


def test_rotation_between_handles_opposite_vectors():
    r = frames.rotation_between([0, 1, 0], [0, -1, 0])
    assert np.allclose(r @ [0, 1, 0], [0, -1, 0])
    assert np.isclose(np.linalg.det(r), 1.0)


def test_world_bbox_of_scaled_rotated_box():
    t = frames.translation([1, 0, 2]) @ frames.rotation_y(math.pi / 2) @ frames.scaling([2, 1, 1])
    lo, hi = frames.world_bbox(t, (1.0, 1.0, 3.0))
    assert np.allclose(lo, [1 - 1.5, 0, 2 - 1.0])
    assert np.allclose(hi, [1 + 1.5, 1, 2 + 1.0])
