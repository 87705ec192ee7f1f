"""Trained on one corpus, asked on another (``evaluate --train --test``): the queries, the ranks, like for like."""

import json
import math
import subprocess
import sys
from dataclasses import replace

import pytest
from support import require_wordnet

from scenesuggest.corpora.corpus import Corpus
from scenesuggest.corpora.crosswalk import crosswalk
from scenesuggest.engines import configure
from scenesuggest.errors import SceneSuggestError
from scenesuggest.evaluation.evaluate import rank_of, summary
from scenesuggest.evaluation.formatting import format_transfer
from scenesuggest.evaluation.transfer import evaluate_transfer
from scenesuggest.learning.priors import Priors
from scenesuggest.suggestion.held_out import held_out_queries
from scenesuggest.suggestion.suggest import Engine, EngineOptions


@pytest.fixture(scope="module")
def small(stanford, ai2thor):
    """40 Stanford scenes to train on, 12 AI2-THOR rooms (of every kind) to ask."""
    require_wordnet()
    train = Corpus(stanford.source, stanford.scenes[:40], stanford.models, stanford.taxonomy)
    test = Corpus(ai2thor.source, ai2thor.scenes[::17], ai2thor.models, ai2thor.taxonomy)
    return train, test


@pytest.fixture(scope="module")
def result(small):
    train, test = small
    specs = [configure({"name": n}) for n in ("paper", "frequency")]
    return evaluate_transfer(train, test, specs, folds=2, explain=2, resamples=200)


@pytest.mark.slow
def test_every_mapped_query_is_asked_and_ranked_as_the_engine_ranks_it(small, result):
    train, test = small
    walk = crosswalk(test, train, require_wordnet())
    engine = Engine(Priors.fit(train.scenes, train.taxonomy), EngineOptions())
    ranks, unmapped = [], 0
    for scene in test.scenes:
        for query, o in held_out_queries(walk.relabel(scene), train.taxonomy, "inferred"):
            if walk.category(scene.objects[o.id].category) is None:
                unmapped += 1
                continue
            ranks.append(rank_of(engine.score(query).total, engine.index.get(o.category), engine.suggestable))
    assert result["skipped"] == 0 and result["queries"] == len(ranks) > 100
    assert result["unmapped_queries"] == unmapped == sum(result["unmapped_by_category"].values()) > 0
    assert set(result["unmapped_by_category"]) <= walk.unmapped
    paper = result["engines"]["paper"]
    assert paper["modes"]["full"]["mrr"] == pytest.approx(summary(ranks)["mrr"])
    assert paper["known_parents"]["n"] + paper["unknown_parents"]["n"] == len(ranks)
    assert result["crosswalk"]["mapped_categories"] == len(walk.matches) - len(walk.unmapped)


@pytest.mark.slow
def test_engines_are_compared_on_the_same_queries_and_like_for_like(result):
    frequency = result["engines"]["frequency"]
    paper = result["engines"]["paper"]
    diff = frequency["vs_first"]
    assert diff["queries"] == result["queries"] and diff["groups"] >= 1
    assert diff["mrr_difference"] == pytest.approx(frequency["modes"]["full"]["mrr"] - paper["modes"]["full"]["mrr"])
    assert diff["low"] <= diff["mrr_difference"] <= diff["high"]
    for block in (paper, frequency):
        lfl = block["like_for_like"]
        assert 0 < lfl["queries"] <= result["queries"] and lfl["folds"] == 2
        assert 0 < lfl["reweighted_in_corpus_mrr"] <= 1 and 0 < lfl["in_corpus_mrr"] <= 1
        mix = lfl["by_category"]  # the in-corpus MRR of each category, weighted by its queries here
        assert sum(m["queries"] for m in mix.values()) == lfl["queries"]
        weighted = sum(m["in_corpus_mrr"] * m["queries"] for m in mix.values()) / lfl["queries"]
        assert lfl["reweighted_in_corpus_mrr"] == pytest.approx(weighted)
        assert lfl["kept"] == pytest.approx(lfl["cross_corpus_mrr"] / lfl["reweighted_in_corpus_mrr"])
        ceiling = lfl["asked_corpus"]  # the asked corpus's own folds, weighted by the same mix
        there = sum(m["asked_corpus_mrr"] * m["queries"] for m in mix.values()) / lfl["queries"]
        assert ceiling["reweighted_mrr"] == pytest.approx(there) and 0 < there <= 1
        assert ceiling["kept"] == pytest.approx(ceiling["reweighted_mrr"] / lfl["reweighted_in_corpus_mrr"])
        assert ceiling["of_ceiling"] == pytest.approx(lfl["cross_corpus_mrr"] / ceiling["reweighted_mrr"])
    assert paper["modes"]["full"]["orient_n"] > 0
    assert "ceiling" in format_transfer(result)


@pytest.mark.slow
def test_the_ceiling_is_the_asked_corpus_in_the_training_vocabulary_by_its_own_folds(small, result):
    """Rebuilt by hand for the paper engine: 2 grouped folds of the asked rooms, relabelled as the queries are."""
    from scenesuggest.corpora.folds import grouped_folds, similar_groups

    train, test = small
    walk = crosswalk(test, train, require_wordnet())
    scenes = [walk.relabel(s, unmapped_unknown=True) for s in test.scenes]
    groups = similar_groups(test.scenes)
    vocabulary = {o.category for s in train.scenes for o in s}
    by_category: dict[str, list[float]] = {}
    for held in grouped_folds(groups, 2, 0):
        engine = Engine(Priors.fit([s for i, s in enumerate(scenes) if i not in set(held)], train.taxonomy),
                        EngineOptions())
        ranked = {n for n, ok in zip(engine.names, engine.suggestable, strict=True) if ok}
        assert ranked and ranked <= vocabulary  # ranked among the training corpus's categories, no unmapped one
        for i in held:
            for query, o in held_out_queries(scenes[i], train.taxonomy, "inferred"):
                ranks = by_category.setdefault(o.category, [])
                ranks.append(rank_of(engine.score(query).total, engine.index.get(o.category), engine.suggestable))
    mix = result["engines"]["paper"]["like_for_like"]["by_category"]
    for category, row in mix.items():
        assert row["asked_corpus_mrr"] == pytest.approx(summary(by_category[category])["mrr"])
    ceiling = result["engines"]["paper"]["like_for_like"]["asked_corpus"]
    assert ceiling["asked_queries"] == sum(len(r) for r in by_category.values())  # no unmapped query is asked


@pytest.mark.slow
def test_like_for_like_needs_a_fold_of_each_corpus(small):
    train, test = small
    one = Corpus(test.source, test.scenes[:1], test.models, test.taxonomy)
    with pytest.raises(SceneSuggestError, match=r"ai2thor has 1 group.* fewer than the 2 folds .*\(give "
                                                r"--no-like-for-like\)") as info:
        evaluate_transfer(train, one, [configure({"name": "paper"})], folds=2, resamples=50)
    assert info.value.field == "folds"
    few = Corpus(test.source, test.scenes[:3], test.models, test.taxonomy)
    with pytest.raises(SceneSuggestError, match=r"\(give --folds [23] or fewer, or --no-like-for-like\)"):
        evaluate_transfer(train, few, [configure({"name": "paper"})], folds=5, resamples=50)
    assert evaluate_transfer(train, one, [configure({"name": "paper"})], like_for_like=False, resamples=50)["queries"]


@pytest.mark.slow
def test_worst_misses_are_explained(result):
    misses = result["explained_misses"]
    assert set(misses) == {"paper", "frequency"}
    for name, rows in misses.items():
        assert len(rows) == 2 and rows[0]["ranks"][name] >= rows[1]["ranks"][name] > 1
        for row in rows:
            assert row["category"] in {e["category"] for e in row["explanation"]}
            assert all(math.isfinite(r) for r in row["ranks"].values() if r is not None)
    rows = misses["paper"]
    text = format_transfer(result)
    assert "worst misses" in text and rows[0]["category"] in text and "like for like" in text
    json.dumps(result, allow_nan=False)  # no Infinity in what --json prints


@pytest.mark.slow
def test_a_parent_the_training_corpus_never_saw_is_unknown(small):
    """Stanford scenes asked of an AI2-THOR engine: an object on an unlabelled model (Unknown) or on an unmapped one
    is on an unknown parent."""
    train, test = small
    into = Corpus(train.source, train.scenes[:12], train.models, train.taxonomy)
    result = evaluate_transfer(test, into, [configure({"name": "paper"})], like_for_like=False, resamples=50)
    walk = crosswalk(into, test, require_wordnet())
    unknown = 0
    for scene in into.scenes:
        for _, o in held_out_queries(walk.relabel(scene), test.taxonomy, "inferred"):
            parent = scene.objects[o.parent].category
            if walk.category(scene.objects[o.id].category) is not None and parent != "Room" and (
                    parent == "Unknown" or walk.category(parent) is None):
                unknown += 1
    paper = result["engines"]["paper"]
    assert paper["unknown_parents"]["n"] == unknown > 0 and paper["known_parents"]["n"] > 0


@pytest.mark.slow
def test_held_out_means_apart(small, ai2thor):
    """The same corpus on both sides, or no query that maps, is said, not scored."""
    train, test = small
    with pytest.raises(SceneSuggestError, match="the same corpus"):
        evaluate_transfer(test, test, like_for_like=False)
    copy = Corpus("json:copy", test.scenes[:2], test.models, test.taxonomy)
    with pytest.raises(SceneSuggestError, match="2 scenes of ai2thor are also in json:copy"):
        evaluate_transfer(copy, test, like_for_like=False)
    renamed = [replace(s, objects={k: replace(o, category="Zzyzx") if o.category != "Room" else o
                                   for k, o in s.objects.items()}) for s in test.scenes[:2]]
    nothing = Corpus(test.source, renamed, test.models, test.taxonomy)
    with pytest.raises(SceneSuggestError, match="no held-out query of ai2thor maps"):
        evaluate_transfer(train, nothing, like_for_like=False)


def run_cli(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "scenesuggest.cli", "evaluate", *args], capture_output=True,
                          text=True)


@pytest.mark.parametrize(("args", "said"), [
    (["--train", "ai2thor"], "--train and --test go together"),
    (["--test", "ai2thor"], "--train and --test go together"),
    (["ai2thor", "--train", "ai2thor", "--test", "ai2thor"], "give SOURCE or --train and --test, not both"),
    (["ai2thor", "--explain", "3"], "--explain and --like-for-like are of --train/--test"),
    (["ai2thor", "--no-like-for-like"], "--explain and --like-for-like are of --train/--test"),
    (["ai2thor", "--like-for-like"], "--explain and --like-for-like are of --train/--test"),  # even at its default
    (["ai2thor", "--explain", "0"], "--explain and --like-for-like are of --train/--test"),
    (["--train", "ai2thor", "--test", "ai2thor", "--group-similar"], "--ablations, --by-category and"),
    (["--train", "ai2thor", "--test", "ai2thor", "--ablations"], "--ablations, --by-category and --group-similar"),
    (["--train", "ai2thor", "--test", "ai2thor", "--no-group-similar"], "--ablations, --by-category and"),
    (["--train", "nowhere:x", "--test", "ai2thor"], "unknown corpus source 'nowhere:x'"),
    (["--train", "json:" + "x" * 5000, "--test", "ai2thor"], "no such folder: 'xxxx"),  # too long a name
    (["--train", "json:a\x01b", "--test", "ai2thor"], "no such folder: 'a\\x01b'"),  # shown, not printed raw
    (["--train", "ai2thor", "--test", "ai2thor", "--explain", "-1"], "-1 is not in the range x>=0"),
    (["--train", "ai2thor", "--test", "ai2thor", "--no-like-for-like"], "the same corpus (ai2thor)"),
    ([], "name the corpus to evaluate"),
])
def test_cli_refuses_what_does_not_go_together(args, said):
    done = run_cli(*args)
    assert done.returncode != 0 and said in done.stderr and "Traceback" not in done.stderr
