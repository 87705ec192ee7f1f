import math

import numpy as np
import pytest

from scenesuggest.scenes import frames, poses


def test_bottom_on_a_floor_is_the_canonical_pose():
    assert np.allclose(poses.attach_rotation("bottom", (0, 1, 0)), np.eye(3))
    t = poses.placement((1.0, 0.0, 2.0), (0, 1, 0), "bottom", (1, 2, 3), 0.0)
    assert np.allclose(t, frames.translation((1.0, 0.0, 2.0)))


@pytest.mark.parametrize("normal", [(1, 0, 0), (0, 0, -1), (-0.6, 0, 0.8)])
def test_back_on_a_wall_faces_out_of_the_wall_and_stays_upright(normal):
    r = poses.attach_rotation("back", normal)
    assert np.allclose(r @ [0, 0, 1], normal)  # front faces out of the wall
    assert np.allclose(r @ [0, 1, 0], [0, 1, 0])  # upright


def test_top_hangs_from_a_ceiling_and_left_attaches_upright():
    assert np.allclose(poses.attach_rotation("top", (0, -1, 0)), np.eye(3))
    r = poses.attach_rotation("left", (1, 0, 0))  # the left face (+X) against a wall facing +X: turned 180°
    assert np.allclose(r @ [1, 0, 0], [-1, 0, 0]) and np.allclose(r @ [0, 1, 0], [0, 1, 0])


def test_placement_puts_the_face_centre_on_the_point():
    size = (0.6, 0.8, 0.02)
    t = poses.placement((0.0, 1.5, -2.0), (0, 0, 1), "back", size, 0.3)
    back_centre = frames.apply(t, [[0, 0.4, -0.01]])[0]
    assert back_centre == pytest.approx([0.0, 1.5, -2.0])


def test_heading_conventions():
    # on floors the heading is the yaw of the front, from +Z towards +X
    assert poses.heading((1, 0, 0), (0, 1, 0)) == pytest.approx(math.pi / 2)
    t = frames.rotation_y(0.7)
    assert poses.object_heading(t, "bottom", (0, 1, 0)) == pytest.approx(0.7)
    # on walls it is the turn away from upright
    assert poses.object_heading(np.eye(4), "back", (0, 0, 1)) == pytest.approx(0.0)
    assert math.isnan(poses.heading((0, 1, 0), (0, 1, 0)))


def test_alpha_adds_to_the_zero_heading():
    for face, normal in [("bottom", (0, 1, 0)), ("back", (1, 0, 0)), ("top", (0, -1, 0))]:
        t = poses.placement((0, 0, 0), normal, face, (1, 1, 1), 1.1)
        h = poses.object_heading(t, face, normal)
        assert poses.wrap(h - poses.zero_heading(face, normal)) == pytest.approx(1.1)


def test_vectorised_placements_match_single_ones():
    faces = ["bottom", "back", "left"]
    sizes = np.array([[1, 2, 3], [0.5, 0.5, 0.1], [0.2, 0.4, 0.6]])
    alphas = np.array([0.0, 0.4, -1.2])
    points = np.array([[0, 0, 0], [1, 2, 3], [-1, 0.5, 2]])
    many = poses.placements(points, (0, 0, 1), faces, sizes, alphas)
    for i in range(3):
        assert np.allclose(many[i], poses.placement(points[i], (0, 0, 1), faces[i], sizes[i], alphas[i]))


def test_plane_offsets_in_the_reference_frame():
    ref = frames.translation((2, 0, 1)) @ frames.rotation_y(math.pi / 2)  # front faces +X
    # a point 0.5 m in front of the reference, on the floor
    assert poses.plane_offset((2.5, 0, 1), (0, 1, 0), ref, radial=False) == pytest.approx([0.0, 0.5])
    assert poses.plane_offset((2.0, 0, 0.3), (0, 1, 0), ref, radial=True) == pytest.approx([0.7, 0.0])
    # on a wall: (along the wall, height above the reference's origin)
    assert poses.plane_offset((2.3, 1.6, -1.0), (0, 0, 1), ref, radial=False)[1] == pytest.approx(1.6)
    assert poses.reference_heading((2.5, 0, 1), (0, 1, 0), ref, radial=False) == pytest.approx(math.pi / 2)
    towards = poses.reference_heading((2.0, 0, 2.0), (0, 1, 0), ref, radial=True)
    assert poses.wrap(towards) == pytest.approx(math.pi)  # from the point, the reference lies towards −Z


def test_geometry_given_once_or_per_row_gives_the_same_as_one_at_a_time():
    """A query asks with one point and one normal for many references, training with one row each: the
    vectorised functions read both shapes alike."""
    from scenesuggest.learning.observations import bearings

    rng = np.random.default_rng(3)
    normals = np.array([[0, 1, 0], [0, 0, 1], [0.6, 0, -0.8], [0, -1, 0], [1e-3, 1, 0]], dtype=float)
    refs = np.stack([frames.translation(rng.normal(size=3)) @ frames.rotation_y(a) @ np.diag([*s, 1.0])
                     for a, s in zip(rng.uniform(-3, 3, 6), rng.uniform(0.5, 2, (6, 3)), strict=True)])
    sizes, radial = rng.uniform(0.2, 2, (6, 3)), np.array([False, True, False, False, True, False])
    for normal in normals:
        point = rng.normal(size=3)
        alone = [(poses.plane_offset(point, normal, t, r), poses.reference_heading(point, normal, t, r),
                  bearings(point, normal, t, s)[0]) for t, s, r in zip(refs, sizes, radial, strict=True)]
        per_row = (np.tile(point, (6, 1)), np.tile(normal, (6, 1)))
        for p, n in ((point, normal), per_row):
            assert np.allclose(poses.plane_offsets(p, n, refs, radial), [a[0] for a in alone])
            assert np.allclose(poses.reference_headings(p, n, refs, radial), [a[1] for a in alone])
            assert np.allclose(bearings(p, n, refs, sizes), [a[2] for a in alone], equal_nan=True)
        directions = rng.normal(size=(6, 3))
        directions[0] = normal  # perpendicular to the plane: no heading
        one = poses.headings(directions, normal)
        assert np.isnan(one[0]) and not np.isnan(one[1:]).any()
        assert np.allclose(poses.headings(directions, np.tile(normal, (6, 1))), one, equal_nan=True)
        assert np.allclose([poses.heading(d, normal) for d in directions], one, equal_nan=True)


def test_turn_about_measures_the_turn_a_person_must_make_on_the_surface():
    up, wall = np.array([0.0, 1.0, 0.0]), np.array([1.0, 0.0, 0.0])  # floor; the left wall, facing +X
    yaw = lambda deg: poses.axis_rotation(up, math.radians(deg)) @ poses.attach_rotation("bottom", up)  # noqa: E731
    assert math.degrees(poses.turn_about(yaw(30), yaw(100), up)) == pytest.approx(70)
    assert math.degrees(poses.turn_about(yaw(170), yaw(-170), up)) == pytest.approx(20)
    hung = poses.attach_rotation("back", wall)
    assert poses.turn_about(hung, hung, wall) == pytest.approx(0, abs=1e-12)  # canonical on a side wall: no turn
    spun = poses.axis_rotation(wall, math.radians(-25)) @ hung
    assert math.degrees(poses.turn_about(hung, spun, wall)) == pytest.approx(-25)
