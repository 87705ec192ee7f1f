"""Orientation error folded by rotational symmetry about the model's up axis."""

import math

import numpy as np
import pytest

from scenesuggest.contract.pose_error import front_angle_deg, pose_error_deg
from scenesuggest.scenes import frames, poses


def yaw(deg):
    return frames.rotation_y(math.radians(deg))


@pytest.mark.parametrize("turn,period,error", [
    (0, 360, 0), (90, 360, 90), (170, 360, 170), (-30, 360, 30),
    (170, 180, 10), (100, 180, 80), (91, 90, 1), (135, 90, 45), (130, 120, 10),
    (77, 0, 0), (180, 0, 0),
])
def test_turns_about_the_up_axis_fold_by_the_period(turn, period, error):
    truth = frames.translation((1, 0, 2)) @ yaw(30) @ frames.scaling((2, 1, 3))
    predicted = frames.translation((1, 0, 2)) @ yaw(30 + turn)
    assert pose_error_deg(predicted, truth, period) == pytest.approx(error, abs=1e-6)


def test_a_wrong_face_is_not_forgiven_by_symmetry():
    truth = np.eye(4)
    lying = frames.linear(poses.axis_rotation([1, 0, 0], math.pi / 2))  # tipped over onto its back
    assert pose_error_deg(lying, truth, 0.0) == pytest.approx(90.0)
    assert pose_error_deg(lying, truth, 360.0) == pytest.approx(90.0)
    assert front_angle_deg(yaw(90), truth) == pytest.approx(90.0)
