"""Scene-type inference from the furniture present, as the paper's system did.

The rules are tried in order; the first whose furniture is in the scene (the category itself or any of
its taxonomy ancestors) names the scene type, otherwise the scene is a plain ``Room``.
"""

from __future__ import annotations

from collections.abc import Iterable

from .taxonomy import Taxonomy

RULES: tuple[tuple[str, frozenset[str]], ...] = (
    ("Bedroom", frozenset({"Bed", "Nightstand", "Dresser"})),
    ("Study", frozenset({"Desk"})),
    ("Kitchen", frozenset({"DiningTable", "KitchenCounter", "Counter", "CounterTop", "StoveBurner", "Fridge"})),
    ("LivingRoom", frozenset({"CoffeeTable", "TVStand", "TV stand", "Sofa", "Couch"})),
)
DEFAULT = "Room"


def infer_scene_type(categories: Iterable[str], taxonomy: Taxonomy | None = None) -> str:
    """The scene type implied by the object categories of a scene."""
    present: set[str] = set()
    for c in categories:
        present.add(c)
        if taxonomy is not None:
            present.update(taxonomy.ancestors(c))
    for scene_type, furniture in RULES:
        if present & furniture:
            return scene_type
    return DEFAULT
