"""Keyword search (SQLite FTS5, BM25) over the model library."""

import pytest

from scenesuggest.library.index import ModelInfo
from scenesuggest.library.search import SearchIndex, fts_query, split_camel


def model(mid, path, name, tags=(), description=""):
    return ModelInfo(id=mid, category=path[-1], category_path=list(path), name=name, tags=list(tags),
                     description=description)


@pytest.fixture
def index():
    return SearchIndex.build([
        model("c1", ["Chair", "OfficeChair"], "desk chair", ["office", "swivel"]),
        model("c2", ["Chair", "SideChair"], "wooden chair"),
        model("c3", ["Chair", "OfficeChair"], "ergonomic task chair"),
        model("d1", ["Desk"], "office desk", ["office", "table"]),
        model("l1", ["Lamp", "DeskLamp"], "desk lamp"),
    ])


def test_split_camel():
    assert split_camel("OfficeChair") == "Office Chair"
    assert split_camel("TVStand") == "TV Stand"


def test_query_syntax_quotes_words_and_prefixes_the_last():
    assert fts_query("Office chai") == '"office" "chai"*'
    assert fts_query("a OR b", any_word=True) == '"a" OR "or" OR "b"*'
    assert fts_query("  ?! ") is None


def test_office_chair_brings_office_chairs_first(index):
    hits = [h.model_id for h in index.search("office chair")]
    assert set(hits[:2]) == {"c1", "c3"}
    assert "c2" not in hits and "d1" not in hits


def test_prefix_matches_while_typing(index):
    assert {h.model_id for h in index.search("offi")} == {"c1", "c3", "d1"}
    assert [h.model_id for h in index.search("lam")] == ["l1"]


def test_stemming_and_fallback_to_any_word(index):
    assert [h.model_id for h in index.search("lamps")] == ["l1"]
    hits = [h.model_id for h in index.search("wooden sofa")]
    assert hits == ["c2"]  # no model has both words: any word matches


def test_empty_and_unmatched_queries(index):
    assert index.search("") == []
    assert index.search("xyzzy") == []
    assert len(index) == 5


def test_search_over_the_stanford_library(stanford):
    idx = SearchIndex.build(stanford.models.values())
    assert len(idx) == 1741
    top = idx.search("office chair", limit=5)
    assert all(h.category == "OfficeChair" for h in top)
    assert idx.search("monitor", limit=3)[0].category == "Monitor"
