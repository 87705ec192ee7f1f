"""Training records: the geometry of a scene's pairs, and which objects have a wall as a reference."""

import math

import numpy as np

from scenesuggest.learning.observations import (
    RADIAL_ASPECT,
    WALL,
    WALL_GAP_M,
    is_radial,
    near_wall,
    scene_observations,
)


def _close(a: float, b: float, tolerance: float = 1e-5) -> bool:
    """Equal angles (radians); the tolerance covers contact normals a few µrad off vertical."""
    return (math.isnan(a) and math.isnan(b)) or abs((a - b + math.pi) % (2 * math.pi) - math.pi) < tolerance


def _yaw(transform) -> float:
    front = np.asarray(transform)[:3, 2]
    return math.atan2(front[0], front[2])


def test_pair_geometry_of_objects_standing_on_floors_and_tops(stanford, ai2thor):
    """θ is the difference of the two fronts' yaws and δ the contact point in the reference's frame (x, z), each
    computed here from the transforms alone; φ is the yaw of the direction towards the reference."""
    checked = 0
    for corpus in (stanford, ai2thor):
        for scene in corpus.scenes[:15]:
            supports, pairs = scene_observations(scene)
            objects = [o for o in scene if o.parent is not None and o.surface_type and o.attachment_face
                       and o.contact_point is not None]
            for p in pairs:
                o = objects[p.support]
                ref = scene.objects[o.parent] if p.relation == "parent" else None
                if p.relation != "parent" or o.attachment_face != "bottom" or o.contact_normal[1] < 1 - 1e-10 \
                        or p.radial or max(abs(ref.transform[1, 2]), abs(o.transform[1, 2])) > 1e-6:
                    continue  # upright objects on level surfaces, where the plane's angles are plain yaws
                assert _close(p.theta, _yaw(o.transform) - _yaw(ref.transform))
                r = ref.transform[:3, :3] / np.linalg.norm(ref.transform[:3, :3], axis=0)
                local = r.T @ (np.asarray(o.contact_point) - ref.transform[:3, 3])
                assert np.allclose(p.offset, local[[0, 2]], atol=1e-9)
                if not math.isnan(p.phi):  # towards the footprint's nearest point, or its centre from inside
                    half = np.asarray(ref.size) * np.linalg.norm(ref.transform[:3, :3], axis=0) / 2
                    centre = ref.transform[:3, 3] + ref.transform[:3, :3] @ (np.asarray(ref.size) * [0, 0.5, 0])
                    at = r.T @ (np.asarray(o.contact_point) - centre)
                    near = np.clip(at, -half, half)
                    inside = abs(near[0] - at[0]) < 1e-9 and abs(near[2] - at[2]) < 1e-9
                    d = (centre - np.asarray(o.contact_point)) if inside else r @ (near - at)
                    assert _close(p.phi, _yaw(o.transform) - math.atan2(d[0], d[2]))
                checked += 1
    assert checked > 200


def test_walls_are_references_of_objects_that_stand_at_them(stanford):
    desks = walls = 0
    for scene in stanford.scenes:
        supports, pairs = scene_observations(scene)
        at_wall = {p.support for p in pairs if p.ref_category == WALL}
        for k, s in enumerate(supports):
            if s.category == "Desk":
                desks += 1
                walls += k in at_wall
    assert desks >= 50 and walls / desks > 0.8  # desks stand against walls


def test_near_wall_and_is_radial_answer_an_array_of_sizes_as_they_answer_each():
    """The query-time checks of a candidate's size (does it stand at the wall, has it a front) give for an array of
    sizes what they give for each size alone, and the wall rule reads the smaller footprint side."""
    sizes = np.array([[0.3, 1.0, 0.3], [2.0, 0.5, 0.4], [0.4, 0.1, 2.0], [1.0, 1.0, 0.98], [0.05, 2.0, 3.0]])
    for distance in (0.0, 0.1, 0.25, 1.0):  # the rule: the contact's distance less half the smaller footprint side
        assert near_wall(distance, sizes).tolist() == [distance - min(s[0], s[2]) / 2 <= WALL_GAP_M for s in sizes]
        assert near_wall(distance, sizes).tolist() == [bool(near_wall(distance, s)) for s in sizes]
    assert is_radial(sizes).tolist() == [max(s[0], s[2]) / min(s[0], s[2]) < RADIAL_ASPECT for s in sizes]
    assert is_radial(sizes).tolist() == [bool(is_radial(s)) for s in sizes]
    assert near_wall(WALL_GAP_M + 0.19, [0.4, 1.0, 2.0]) and not near_wall(WALL_GAP_M + 0.21, [0.4, 1.0, 2.0])
