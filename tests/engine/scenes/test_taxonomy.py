import pytest

from scenesuggest.errors import SceneSuggestError
from scenesuggest.scenes.taxonomy import Taxonomy


def test_from_paths_keeps_the_most_frequent_parent():
    t = Taxonomy.from_paths([["Table", "DiningTable"], ["Table", "DiningTable"], ["Furniture", "DiningTable"],
                             ["Chair", "OfficeChair"]])
    assert t.parent("DiningTable") == "Table"
    assert t.path("OfficeChair") == ["Chair", "OfficeChair"]
    assert t.ancestors("Table") == []


def test_from_paths_drops_edges_that_would_close_a_cycle():
    t = Taxonomy.from_paths([["A", "B"], ["A", "B"], ["B", "A"]])
    assert t.parent("B") == "A" and t.parent("A") is None


def test_cycles_are_rejected():
    with pytest.raises(SceneSuggestError, match="cycle"):
        Taxonomy({"A": "B", "B": "A"})


def test_save_load_round_trip(tmp_path):
    t = Taxonomy({"Mug": "Dish", "Dish": "Kitchenware"})
    t.save(tmp_path / "t.json")
    assert Taxonomy.load(tmp_path / "t.json").parents == t.parents
    (tmp_path / "bad.json").write_text('{"parents": {"Mug": 3}}')
    with pytest.raises(SceneSuggestError) as info:
        Taxonomy.load(tmp_path / "bad.json")
    assert info.value.field == "parents"
