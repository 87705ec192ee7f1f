import pytest

from scenesuggest.errors import SceneSuggestError
from scenesuggest.taxonomy import MIN_OBSERVATIONS, Taxonomy


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


def test_back_off_climbs_to_the_first_category_with_enough_observations():
    t = Taxonomy({"OfficeChair": "Chair", "Chair": "Seat", "Seat": "Furniture"})
    counts = {"OfficeChair": 2, "Chair": 4, "Seat": 40}
    assert MIN_OBSERVATIONS == 5
    assert t.back_off("OfficeChair", lambda c: counts.get(c, 0)) == "Seat"
    assert t.back_off("Chair", lambda c: 10) == "Chair"
    assert t.back_off("OfficeChair", lambda c: 0) is None
    assert t.back_off("Unrelated", lambda c: counts.get(c, 0)) is None


def test_back_off_on_the_stanford_taxonomy(stanford):
    counts = {}
    for o in stanford.objects():
        counts[o.category] = counts.get(o.category, 0) + 1
    rare = next(c for c, n in counts.items() if n < 5 and stanford.taxonomy.parent(c) and counts.get(
        stanford.taxonomy.parent(c), 0) >= 5)
    assert stanford.taxonomy.back_off(rare, lambda c: counts.get(c, 0)) == stanford.taxonomy.parent(rare)


def test_save_load_round_trip(tmp_path):
    t = Taxonomy({"Mug": "Dish", "Dish": "Kitchenware"})
    t.save(tmp_path / "t.json")
    assert Taxonomy.load(tmp_path / "t.json").parents == t.parents
    (tmp_path / "bad.json").write_text('{"parents": {"Mug": 3}}')
    with pytest.raises(SceneSuggestError) as info:
        Taxonomy.load(tmp_path / "bad.json")
    assert info.value.field == "parents"
