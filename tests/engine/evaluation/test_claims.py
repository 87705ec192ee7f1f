"""The paper's qualitative claims, checked on the Stanford corpus.

Priors are learned from every scene except scene00027 (a study: a desk against the back wall carrying a
computer, keyboard, two speakers…), and the queries are made in that held-out scene.
"""

import numpy as np
import pytest

from scenesuggest.learning.priors import Priors
from scenesuggest.scenes import poses
from scenesuggest.suggestion.suggest import ContextQuery, Engine

HELD_OUT = "scene00027"
DESK = "1"  # its desk; the room is "0"; the back wall is the plane z = -6.17 m, facing +Z
DRINKS = {"Mug", "Glass", "Cup", "DrinkBottle", "SodaCan", "WineBottle", "Teacup", "Bottle", "BeerBottle",
          "MilkCarton"}


@pytest.fixture(scope="module")
def scene(stanford):
    return next(s for s in stanford.scenes if s.id == HELD_OUT)


@pytest.fixture(scope="module")
def engine(stanford):
    return Engine(Priors.fit([s for s in stanford.scenes if s.id != HELD_OUT], stanford.taxonomy))


def ranks(results) -> dict[str, int]:
    return {s.category: s.rank for s in results}


def desk_top(scene):
    lo, hi = scene.objects[DESK].world_bbox()
    return ((lo[0] + hi[0]) / 2, hi[1], (lo[2] + hi[2]) / 2)


def cleared(scene, parent):
    for child in scene.children(parent):
        scene = scene.without(child.id)
    return scene


def test_computer_peripherals_rank_high_on_a_desk_top(engine, scene):
    results = engine.suggest(ContextQuery(cleared(scene, DESK), DESK, desk_top(scene), (0, 1, 0)), top=5)
    peripherals = {"Monitor", "Keyboard", "ComputerMouse", "Speaker", "MousePad", "Desktop", "Laptop"}
    assert len(peripherals & {s.category for s in results}) >= 2
    assert results[0].category in peripherals


def test_wall_above_the_desk_changes_with_height(engine, scene):
    """Sockets low, switches at arm height, wall art and clocks high, on the same spot of the same wall."""
    def at(height):
        return ranks(engine.suggest(ContextQuery(scene, "0", (7.5, height, -6.17), (0, 0, 1))))

    low, arm, high, higher = at(0.5), at(1.3), at(2.2), at(2.6)
    assert low["PowerSocket"] == 1 and low["PowerSocket"] < high["PowerSocket"]
    assert arm["LightSwitch"] == 1 and arm["LightSwitch"] < min(low["LightSwitch"], high["LightSwitch"])
    assert min(high["Poster"], high["WallArt"]) == 1
    assert high["Poster"] < min(high["PowerSocket"], high["LightSwitch"])
    assert higher["WallClock"] == 1 and higher["WallClock"] < low["WallClock"]


def test_a_chair_in_front_of_the_desk_faces_it(engine, scene):
    desk = scene.objects[DESK]
    without_chairs = scene
    for o in scene.children("0"):
        if "Chair" in o.category:
            without_chairs = without_chairs.without(o.id)
    front = poses.rotation_of(desk.transform)[:, 2]
    point = desk.transform[:3, 3] + 0.7 * front
    point[1] = 0.0
    results = engine.suggest(ContextQuery(without_chairs, "0", point, (0, 1, 0)), "full")
    chair = next(s for s in results if s.category == "OfficeChair")
    assert chair.rank <= 3
    chair_front = chair.placement[:3, 2] / np.linalg.norm(chair.placement[:3, 2])
    assert np.degrees(np.arccos(np.dot(chair_front, -front))) <= 20  # faces the desk (whose front is +Z)


def test_a_second_speaker_still_scores_but_a_second_keyboard_does_not(engine, scene):
    speakers = [o.id for o in scene.children(DESK) if o.category == "Speaker"]
    one_each = scene.without(speakers[1])  # one speaker, one keyboard on the desk
    point = desk_top(scene)
    with_one = {s.category: s for s in engine.suggest(ContextQuery(one_each, DESK, point, (0, 1, 0)))}
    empty = {s.category: s for s in engine.suggest(ContextQuery(cleared(scene, DESK), DESK, point, (0, 1, 0)))}
    speaker_kept = with_one["Speaker"].terms["occurrence"] / empty["Speaker"].terms["occurrence"]
    keyboard_kept = with_one["Keyboard"].terms["occurrence"] / empty["Keyboard"].terms["occurrence"]
    assert speaker_kept > 0.6 and keyboard_kept < 0.1
    assert with_one["Speaker"].rank <= 5 and with_one["Keyboard"].rank > 10


def bedroom_furniture(scenes):
    for s in scenes:
        if s.scene_type == "Bedroom":
            for o in s:
                if o.category in ("Nightstand", "Dresser", "ChestOfDrawers"):
                    lo, hi = o.world_bbox()
                    yield s, o, ((lo[0] + hi[0]) / 2, hi[1], (lo[2] + hi[2]) / 2)


def test_drinks_in_bedrooms_follow_the_corpus(stanford):
    """The paper: drink-like categories do not appear in bedrooms. This corpus disagrees — its 15 bedrooms
    hold 14 drinks (5 cups and a wine bottle on nightstands, 3 bottles on dressers) — so the claim is
    tested as a mechanism: trained on the same scenes with the bedrooms' drinks removed, no drink reaches
    the top 10 on any bedroom chest, while the same queries in a kitchen context bring drinks."""
    bedrooms = [s for s in stanford.scenes if s.scene_type == "Bedroom"]
    assert sum(o.category in DRINKS for s in bedrooms for o in s) == 14
    training = []
    for s in stanford.scenes:
        if s.scene_type == "Bedroom":
            for o in list(s):
                if o.id in s.objects and o.category in DRINKS:
                    s = s.without(o.id)
        training.append(s)
    engine = Engine(Priors.fit(training, stanford.taxonomy))
    queries = list(bedroom_furniture(training))
    assert len(queries) >= 20
    for s, o, point in queries:
        top = {x.category for x in engine.suggest(ContextQuery(s, o.id, point, (0, 1, 0)), top=10)}
        assert not top & DRINKS, (s.id, o.category, top & DRINKS)
    # the same queries in a kitchen context do bring drinks
    in_kitchen = [bool({x.category for x in engine.suggest(ContextQuery(s, o.id, point, (0, 1, 0),
                                                                         scene_type="Kitchen"), top=10)} & DRINKS)
                  for s, o, point in queries]
    assert sum(in_kitchen) >= len(queries) / 4
