"""WordNet read from Debian's files, and categories mapped between Stanford and AI2-THOR through it."""

from pathlib import Path

import pytest
from support import require_wordnet

from scenesuggest.corpora.corpus import Corpus
from scenesuggest.corpora.crosswalk import DECISIONS, crosswalk, words
from scenesuggest.corpora.wordnet import PHYSICAL_ENTITY, ROOT, WordNet, synset_id
from scenesuggest.errors import SceneSuggestError
from scenesuggest.scenes.scene import ROOM, UNKNOWN
from scenesuggest.suggestion.suggestable import suggestable

CHAIR, ARMCHAIR = "n03001627", "n02738535"


@pytest.fixture(scope="module")
def wn():
    return require_wordnet()


def test_synset_ids_take_the_short_spelling_and_refuse_anything_else():
    assert synset_id("n3001627") == CHAIR == synset_id(CHAIR)
    for bad in ("3001627", "v03001627", "n", "n0300x627", "n123456789", ""):
        with pytest.raises(SceneSuggestError, match="not a WordNet noun synset"):
            synset_id(bad)


def test_wordnet_reads_senses_lemmas_and_hypernyms(wn):
    assert wn.senses("chair")[0] == CHAIR and wn.senses("Chairs")[0] == CHAIR
    assert wn.senses("garbage can") == wn.senses("garbage_can") and wn.senses("no_such_thing_here") == ()
    # plurals: WordNet's exceptions, then its suffix rules in its order
    for plural, singular in (("shelves", "shelf"), ("knives", "knife"), ("oranges", "orange"), ("boxes", "box"),
                             ("vases", "vase"), ("benches", "bench")):
        first = wn.senses(singular)
        assert wn.senses(plural)[:len(first)] == first, plural  # then other bases' ("vases": also vas)
    glasses = wn.senses("glasses")  # a lemma itself (spectacles), and then a plural of glass
    assert glasses[0] == wn.senses("spectacles")[0] and set(wn.senses("glass")) < set(glasses)
    assert set(wn.senses("axis")) < set(wn.senses("axes"))  # noun.exc names both axis and ax
    chair = wn.synset("n3001627")
    assert chair.lemmas == ("chair",) and "seat for one person" in chair.gloss
    assert dict(wn.ancestors(ARMCHAIR))[CHAIR] == 1
    assert wn.is_thing(CHAIR) and wn.depth(PHYSICAL_ENTITY) == 1 and wn.depth(ROOT) == 0
    assert wn.depth(CHAIR) == 1 + min(wn.depth(h) for h in chair.hypernyms) == 9
    cabinet = wn.senses("cabinet")
    assert wn.is_thing(cabinet[0]) and not wn.is_thing(cabinet[1])  # furniture; the ministers
    assert not any(wn.is_thing(s) for s in wn.senses("idea"))
    with pytest.raises(SceneSuggestError, match="no WordNet noun synset"):
        wn.synset("n00000002")


def test_missing_or_broken_wordnet_is_said_not_thrown(tmp_path: Path):
    with pytest.raises(SceneSuggestError, match="apt-get install wordnet-base"):
        WordNet(tmp_path)
    (tmp_path / "index.noun").write_text("chair n x\n", encoding="utf-8")
    (tmp_path / "data.noun").write_text("", encoding="utf-8")
    with pytest.raises(SceneSuggestError, match="not a WordNet index line") as e:
        WordNet(tmp_path)
    assert e.value.line == 1
    (tmp_path / "index.noun").write_text("chair n 1 0 1 0 00000005\n", encoding="utf-8")
    (tmp_path / "data.noun").write_text("head\n00000005 06 n zz\n", encoding="utf-8")
    with pytest.raises(SceneSuggestError, match="not a WordNet synset line"):
        WordNet(tmp_path).synset("n00000005")
    (tmp_path / "data.noun").write_text("head\nx00000006 06 n 01 chair 0 000 | g\n", encoding="utf-8")
    with pytest.raises(SceneSuggestError, match="no WordNet noun synset"):  # the offset is not where a line starts
        WordNet(tmp_path).synset("n00000006")


def test_words_of_category_names():
    assert words("GarbageCan") == ["garbage", "can"] and words("TVStand") == ["tv", "stand"]
    assert words("4Shelves") == ["shelves"] and words("saucebottle") == ["saucebottle"]


@pytest.fixture(scope="module")
def ai2thor_into_stanford(ai2thor, stanford, wn):
    return crosswalk(ai2thor, stanford, wn)


@pytest.fixture(scope="module")
def stanford_into_ai2thor(ai2thor, stanford, wn):
    return crosswalk(stanford, ai2thor, wn)


def test_ai2thor_types_map_into_stanford_categories(ai2thor_into_stanford, stanford):
    walk = ai2thor_into_stanford
    known = {o.category for s in stanford.scenes for o in s}
    expected = {"Chair": ("Chair", "name"), "AlarmClock": ("TableClock", "hypernym"),
                "GarbageCan": ("TrashBin", "synset"), "Sofa": ("Couch", "synset"),
                "ArmChair": ("Chair", "hypernym"), "Television": ("TV", "synset"), "CD": ("CompactDisk", "decided"),
                "Drawer": (None, "decided"), "Window": (None, "decided"), "StoveKnob": (None, "unmapped"),
                "Spoon": ("Utensils", "parent"),  # a parent maps by its name or synset only:
                "BaseballBat": (None, "unmapped")}  # "sports equipment" would find shoes
    for name, (target, via) in expected.items():
        assert (walk.matches[name].category, walk.matches[name].via) == (target, via), name
    assert stanford.taxonomy.parent(walk.category("Bed")) == "Bed"  # Stanford has only kinds of bed
    for name, match in walk.matches.items():
        assert match.category is None or (match.category in known and suggestable(match.category)), name
    assert walk.category(ROOM) == ROOM and ROOM not in walk.matches
    d = walk.to_dict()
    assert d["mapped_categories"] + d["unmapped_categories"] == d["categories"] == len(walk.matches)
    assert d["unmapped_instances"] == sum(walk.counts[c] for c in walk.unmapped) > 0
    assert sum(d["by_rule"].values()) == d["categories"]


def test_stanford_categories_map_into_ai2thor_types(stanford_into_ai2thor, ai2thor):
    walk = stanford_into_ai2thor
    assert walk.category("TrashBin") == "GarbageCan" and walk.category("OfficeChair") == "Chair"
    # found only through the models' WordNet lemmas (ShapeNetSem's wnlemmas): "4Shelves" names no sense itself
    assert (walk.matches["4Shelves"].category, walk.matches["4Shelves"].via) == ("Shelf", "synset")
    assert walk.category("Keyboard") is None  # AI2-THOR has no keyboards
    assert UNKNOWN not in walk.matches  # a placeholder is never mapped
    types = {o.category for s in ai2thor.scenes for o in s}
    assert all(m.category in types for m in walk.matches.values() if m.category is not None)


def test_every_decision_names_categories_that_exist(stanford, ai2thor):
    """A decision about a category one corpus no longer has, or into one the other lacks, is stale."""
    vocabulary = {"stanford": {o.category for s in stanford.scenes for o in s},
                  "ai2thor": {o.category for s in ai2thor.scenes for o in s}}
    nodes = {"stanford": set(stanford.taxonomy.parents.values()), "ai2thor": set(ai2thor.taxonomy.parents.values())}
    assert set(DECISIONS) == {("ai2thor", "stanford"), ("stanford", "ai2thor")}
    for (asked, trained), decided in DECISIONS.items():
        for name, (target, reason) in decided.items():
            assert name in vocabulary[asked] | nodes[asked], (asked, name)  # a category, or a parent of some
            assert target is None or target in vocabulary[trained], (asked, name, target)
            assert reason


def test_a_decided_parent_ends_the_walk(stanford_into_ai2thor):
    walk = stanford_into_ai2thor
    assert (walk.matches["WineGlass"].category, walk.matches["WineGlass"].via,
            walk.matches["WineGlass"].through) == ("Cup", "parent", "DrinkingUtensil")  # decided: a cup
    assert walk.category("Bear") is None  # its parent ToyFigure is decided unmapped: no further up


def test_decisions_hold_for_their_pair_of_corpora_only(ai2thor, stanford, wn):
    """A decision names a category of one training corpus: another (a subset without it, or a corpus of another
    kind) leaves the category unmapped, or maps it by the rules."""
    some = [s for s in stanford.scenes if not any(o.category == "CompactDisk" for o in s)]
    without = crosswalk(ai2thor, Corpus(stanford.source, some, stanford.models, stanford.taxonomy), wn)
    assert without.matches["CD"].category is None and "no CompactDisk" in without.matches["CD"].through
    native = crosswalk(ai2thor, Corpus("json:elsewhere", stanford.scenes, stanford.models, stanford.taxonomy), wn)
    assert all(m.via != "decided" for m in native.matches.values())
    assert native.matches["Window"].via == "hypernym"  # what the decision corrects


def test_relabelled_scenes_speak_the_training_vocabulary(ai2thor_into_stanford, ai2thor, stanford):
    walk = ai2thor_into_stanford
    known = {o.category for s in stanford.scenes for o in s}
    scene = ai2thor.scenes[0]
    relabelled = walk.relabel(scene)
    assert list(relabelled.objects) == list(scene.objects) and scene.objects != relabelled.objects
    for key, o in relabelled.objects.items():
        original = scene.objects[key].category
        if original in walk.unmapped:
            assert o.category == "unmapped:" + original and o.category not in known
        else:
            assert o.category in known, original
        assert (o.transform == scene.objects[key].transform).all() and o.parent == scene.objects[key].parent
