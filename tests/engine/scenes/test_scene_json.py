import json

import numpy as np
import pytest

from scenesuggest.errors import SceneSuggestError
from scenesuggest.scenes import frames, scene_json
from scenesuggest.scenes.scene import ObjectInstance, Scene


def small_scene() -> Scene:
    s = Scene("demo", "Study", source="test")
    s.objects["room"] = ObjectInstance("room", "room01", "Room", frames.scaling([4.0, 2.7, 5.0]), (1.0, 1.0, 1.0))
    desk_t = frames.translation([0.1, 0.0, -1.9]) @ frames.rotation_y(0.1234567890123)
    s.objects["desk"] = ObjectInstance("desk", "m1", "Desk", desk_t, (1.2, 0.75, 0.6), parent="room",
                                       surface_type="up_interior", attachment_face="bottom",
                                       contact_point=(0.1, 0.0, -1.9), contact_normal=(0.0, 1.0, 0.0))
    lamp_t = frames.translation([0.3, 0.75, -1.8]) @ frames.rotation_y(-2.0 / 3.0)
    s.objects["lamp"] = ObjectInstance("lamp", "m2", "DeskLamp", lamp_t, (0.2, 0.45, 0.2), parent="desk",
                                       surface_type="up_exterior", attachment_face="bottom",
                                       contact_point=(0.3, 0.75, -1.8), contact_normal=(0.0, 1.0, 0.0))
    return s


def test_save_load_round_trips_exactly(tmp_path):
    s = small_scene()
    path = tmp_path / "s.json"
    scene_json.save(s, path)
    loaded = scene_json.load(path)
    assert loaded.objects == s.objects
    assert (loaded.id, loaded.scene_type, loaded.source) == (s.id, s.scene_type, s.source)
    assert scene_json.dumps(loaded) == path.read_text()


def test_real_corpus_scene_round_trips(stanford):
    scene = stanford.scenes[5]
    again = scene_json.loads(scene_json.dumps(scene))
    assert again.objects == scene.objects
    assert all(np.array_equal(a.transform, b.transform) for a, b in zip(again, scene, strict=True))


def test_an_empty_source_round_trips():
    s = small_scene()
    s.source = ""
    assert scene_json.loads(scene_json.dumps(s)).source == ""


def test_format_is_versioned_and_column_major():
    doc = json.loads(scene_json.dumps(small_scene()))
    assert doc["format"] == "scenesuggest-scene" and doc["version"] == 1
    desk = doc["objects"][1]
    assert desk["transform"][12:15] == [0.1, 0.0, -1.9]


def line_of(text: str, needle: str, occurrence: int = 1) -> int:
    pos = -1
    for _ in range(occurrence):
        pos = text.index(needle, pos + 1)
    return text.count("\n", 0, pos) + 1


def load_error(text: str) -> SceneSuggestError:
    with pytest.raises(SceneSuggestError) as info:
        scene_json.loads(text, file="bad.json")
    return info.value


def test_bad_number_names_file_line_and_field():
    text = scene_json.dumps(small_scene())
    doc = json.loads(text)
    doc["objects"][2]["size"][1] = "tall"
    text = json.dumps(doc, indent=1)
    err = load_error(text)
    assert (err.file, err.field) == ("bad.json", "size")
    assert err.line == line_of(text, '"size"', 3)
    assert "bad number 'tall'" in str(err) and str(err).startswith(f"bad.json:{err.line}: field 'size'")


def test_unknown_field_is_an_error():
    doc = json.loads(scene_json.dumps(small_scene()))
    doc["objects"][1]["colour"] = "red"
    text = json.dumps(doc, indent=1)
    err = load_error(text)
    assert err.field == "colour" and err.line == line_of(text, '"colour"')
    assert "unknown field" in str(err)


def test_missing_parent_is_an_error():
    doc = json.loads(scene_json.dumps(small_scene()))
    doc["objects"][2]["parent"] = "shelf"
    text = json.dumps(doc, indent=1)
    err = load_error(text)
    assert err.field == "parent" and "'shelf'" in err.message
    assert err.line == line_of(text, '"id": "lamp"') - 1  # the object's opening brace


def test_cycle_in_support_tree_is_an_error():
    doc = json.loads(scene_json.dumps(small_scene()))
    doc["objects"][1]["parent"] = "lamp"
    err = load_error(json.dumps(doc, indent=1))
    assert err.field == "parent" and "cycle" in err.message
    assert "desk" in err.message and "lamp" in err.message


def test_malformed_json_reports_line():
    text = scene_json.dumps(small_scene()).replace('"Desk"', '"Desk",,', 1)
    err = load_error(text)
    assert err.line == line_of(text, '"Desk",,') and "not valid JSON" in err.message


def test_unsupported_version():
    doc = json.loads(scene_json.dumps(small_scene()))
    doc["version"] = 99
    err = load_error(json.dumps(doc, indent=1))
    assert err.field == "version" and err.line == 3
