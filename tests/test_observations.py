"""Training records: the geometry of a scene's pairs, computed at once, is that of each pair on its own."""

import math

import numpy as np

from scenesuggest import poses
from scenesuggest.observations import WALL, context, pair_geometry, scene_observations


def _close(a: float, b: float) -> bool:
    return (math.isnan(a) and math.isnan(b)) or abs((a - b + math.pi) % (2 * math.pi) - math.pi) < 1e-9


def test_batched_pair_geometry_equals_the_per_pair_functions(stanford, ai2thor):
    for corpus in (stanford, ai2thor):
        for scene in corpus.scenes[:12]:
            supports, pairs = scene_observations(scene)
            objects = [o for o in scene if o.parent is not None and o.surface_type and o.attachment_face
                       and o.contact_point is not None]
            assert len(objects) == len(supports)
            by_support = {}
            for p in pairs:
                if p.relation != "wall":
                    by_support.setdefault(p.support, []).append(p)
            for k, o in enumerate(objects):
                normal = np.asarray(o.contact_normal, dtype=float)
                heading = poses.object_heading(o.transform, o.attachment_face, normal)
                for (ref, _), p in zip(context(scene, o), by_support.get(k, []), strict=True):
                    offset, theta, phi = pair_geometry(o.contact_point, normal, heading, ref)
                    assert p.ref_category == ref.category and np.allclose(offset, p.offset, atol=1e-12)
                    assert _close(theta, p.theta) and _close(phi, p.phi)


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
