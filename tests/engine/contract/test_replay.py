"""Trials rebuilt from their events: the event vocabulary's object states, the pure replay, the server's check at
"done", and how close a scene came to its target."""

import json

import pytest
from statehelp import ROOM, event, insert, obj

from scenesuggest.contract.event_schema import json_schema
from scenesuggest.contract.events import EventError, validate_batch
from scenesuggest.contract.replay import ReplayUnavailable, differences, final_scene, replay, scene_at
from scenesuggest.contract.scoring import BACKOFF_CREDIT, category_credit, closeness


def test_replay_follows_inserts_moves_deletes_and_undos():
    a0, a1, b0 = obj("a", 1.0), obj("a", 2.0), obj("b", 0.0, 1.0, parent="a")
    events = [insert(0, a0), event(1, "camera", action="orbit"), insert(2, b0),
              event(3, "move_end", object="a", distance=1.0, objects=[a1, {**b0, "parent": "a"}]),
              event(4, "delete", object="a", objects=[{"id": "a", "removed": True}, {"id": "b", "removed": True}]),
              event(5, "undo", action="delete", objects=[a1, b0]),
              event(6, "undo", action="move", objects=[a0, b0])]
    scenes = replay([ROOM], events)
    assert len(scenes) == len(events) and scenes[1] is scenes[0]  # a camera turn changes nothing
    assert sorted(scenes[2]) == ["a", "b", "room"] and scenes[3]["a"]["transform"][12] == 2.0
    assert sorted(scenes[4]) == ["room"]  # the delete took the child with it
    assert scenes[6]["a"] == a0 and sorted(scenes[6]) == ["a", "b", "room"]  # the undone move restored the pose
    assert scene_at([ROOM], events, events[3]["t"] - 1)["a"]["transform"][12] == 1.0
    assert scene_at([ROOM], events, 0.0) == {"room": ROOM}
    assert differences(final_scene([ROOM], events), [ROOM, a0, b0]) == []
    moved = {**a0, "transform": a0["transform"][:12] + [1.0 + 1e-3, 0.0, 0.0, 1.0]}
    assert differences(final_scene([ROOM], events), [ROOM, moved]) == ["b: only in the replay",
                                                                     "a: transform differs"]


def test_events_without_object_states_cannot_be_replayed():
    with pytest.raises(ReplayUnavailable, match="vocabulary 1"):
        replay([ROOM], [event(0, "insert", object="a", model="m", category="C", rank=1, source="fixed")])


# --- the vocabulary -------------------------------------------------------------------------------------------
@pytest.mark.parametrize(("states", "field"), [
    (None, "events[0].payload.objects"),
    ([{**obj("a"), "transform": [1.0] * 15}], "events[0].payload.objects[0].transform"),
    ([{**obj("a"), "size": [0.5, -0.1, 0.5]}], "events[0].payload.objects[0].size"),
    ([{**obj("a"), "attachment_face": "side"}], "events[0].payload.objects[0].attachment_face"),
    ([{**obj("a"), "colour": "red"}], "events[0].payload.objects[0].colour"),
    ([{"id": "a", "removed": False}], "events[0].payload.objects[0]"),
    ([{"id": "a\x00", "removed": True}], "events[0].payload.objects[0].id"),
    ([{k: v for k, v in obj("a").items() if k != "parent"}], "events[0].payload.objects[0].parent"),
])
def test_scene_changes_of_vocabulary_2_must_carry_valid_states(states, field):
    e = insert(0, obj("a"))
    if states is None:
        del e["payload"]["objects"]
    else:
        e["payload"]["objects"] = states
    with pytest.raises(EventError) as info:
        validate_batch([e], 2)
    assert info.value.field == field
    ok = insert(0, obj("a"))
    assert validate_batch([ok], 2)[0]["payload"]["objects"][0]["id"] == "a"
    with pytest.raises(EventError, match="unknown field"):  # version 1 pages never sent states
        validate_batch([ok], 1)


def test_the_event_schema_describes_object_states():
    schema = json_schema()
    assert schema["x-vocabulary-version"] == 2
    insert_branch = next(b for b in schema["allOf"] if b["if"]["properties"]["type"]["const"] == "insert")
    payload = insert_branch["then"]["properties"]["payload"]
    assert "objects" in payload["required"] and "removed" in json.dumps(payload["properties"]["objects"])
    old = next(b for b in json_schema(1)["allOf"] if b["if"]["properties"]["type"]["const"] == "insert")
    assert "objects" not in old["then"]["properties"]["payload"]["properties"]


# --- the server's check at "done" -------------------------------------------------------------------------------


# --- how close to the target ----------------------------------------------------------------------------------
def _parent(category):
    return {"Chair": "Seat", "Stool": "Seat", "Seat": None}.get(category)


def test_a_rebuilt_scene_scores_1_and_each_shortfall_costs():
    target = [ROOM, obj("a", 1.0, 0.0), obj("b", -1.0, 0.0, model="m-table", category="Table")]
    periods = {"m-chair": 360.0, "m-table": 180.0}.get

    def score(scene):
        return closeness([ROOM, *scene], target, ["room"], _parent, periods)

    assert score([obj("x", 1.0, 0.0), obj("y", -1.0, 0.0, model="m-table", category="Table")]).score == 1.0
    assert score([obj("x", 1.0, 0.0)]).score == pytest.approx(0.5)  # the table is missing
    three = score([obj("x", 1.0), obj("y", -1.0, model="m-table", category="Table"), obj("z", 5.0)])
    assert three.score == pytest.approx(2 / 3) and three.extra == ("z",)
    half_way = score([obj("x", 1.0 + 0.275), obj("y", -1.0, model="m-table", category="Table")])
    assert half_way.score == pytest.approx((0.5 + 1.0) / 2) and half_way.position_error_m == pytest.approx(0.1375)
    turned = score([obj("x", 1.0, turn_deg=50.0), obj("y", -1.0, model="m-table", category="Table",
                                                         turn_deg=180.0)])
    assert turned.score == pytest.approx((0.5 + 1.0) / 2)  # 50° costs half; a table turned by its period nothing
    stool = score([obj("x", 1.0, category="Stool", model="m-stool"), obj("y", -1.0, model="m-table",
                                                                          category="Table")])
    assert stool.score == pytest.approx((BACKOFF_CREDIT + 1.0) / 2)
    # the assignment prefers the right category to the nearer object
    swapped = score([obj("x", -1.0, 0.0), obj("y", 1.0, 0.0, model="m-table", category="Table")])
    assert {(m.target, m.placed) for m in swapped.matches} == {("a", "x"), ("b", "y")} and swapped.score == 0.0
    assert category_credit("Sofa", "Chair", _parent) == 0.0 and category_credit("Seat", "Chair", _parent) == 0.5


def test_an_event_gives_each_object_one_state():
    a = obj("a")
    with pytest.raises(EventError) as info:
        validate_batch([insert(0, a) | {"payload": insert(0, a)["payload"] | {"objects": [a, {**a, "model_id": "x"}]}}])
    assert info.value.field == "events[0].payload.objects[1].id"
