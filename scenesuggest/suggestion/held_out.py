"""The queries a corpus scene asks when its objects are held out one at a time — as ``evaluate`` asks them and as
the learned engine trains on them: each supported object with a contact is taken out with everything it supports,
and the engine is asked on its parent at its contact point and normal. An object of a placeholder category
(:mod:`.suggestable`: Unknown) is no query, since no one wants one.

The room's type a query carries is one of :data:`SCENE_TYPES`:

- ``inferred`` (the default, leak-free): a type the corpus inferred from the scene's objects
  (``Scene.type_from_objects``: Stanford's, RoboTHOR's) is inferred again from what is left — never from the queried
  object or what it supports; a type declared apart from the objects (AI2-THOR's room groups, a scene file's) is
  kept, as a study's queries carry the type its target file declares whatever the participant has placed;
- ``given``: the scene's own type, as the corpus set it. For Stanford that reading leaks the answer: its types were
  inferred from every object, the queried one too (a desk makes its room a Study, and "what stands here?" then
  answers Desk).

A corpus converted to the native format (``json:``) declares the types it was given, so a Stanford corpus read back
that way is read as ``given``.
"""

from __future__ import annotations

from collections.abc import Iterator

from ..errors import SceneSuggestError
from ..scenes.scene import ObjectInstance, Scene
from ..scenes.scene_types import infer_scene_type
from ..scenes.taxonomy import Taxonomy
from .query import ContextQuery
from .suggestable import suggestable

SCENE_TYPES = ("inferred", "given")
DEFAULT_SCENE_TYPE = "inferred"


def check_scene_type(scene_type: str) -> None:
    """Raise SceneSuggestError (field ``scene_type``) unless ``scene_type`` is one of :data:`SCENE_TYPES`."""
    if scene_type not in SCENE_TYPES:
        raise SceneSuggestError(f"expected one of {', '.join(SCENE_TYPES)}", field="scene_type")


def held_out_queries(scene: Scene, taxonomy: Taxonomy | None,
                     scene_type: str = DEFAULT_SCENE_TYPE) -> Iterator[tuple[ContextQuery, ObjectInstance]]:
    """(query, the object held out) for every object of ``scene`` that makes a query, in the scene's order."""
    check_scene_type(scene_type)
    for o in scene:
        if o.parent is None or o.contact_point is None or o.contact_normal is None or not suggestable(o.category):
            continue
        rest = scene.without(o.id)
        room = (infer_scene_type((x.category for x in rest), taxonomy)
                if scene_type == "inferred" and scene.type_from_objects else scene.scene_type)
        yield ContextQuery(rest, o.parent, o.contact_point, o.contact_normal, scene_type=room), o
