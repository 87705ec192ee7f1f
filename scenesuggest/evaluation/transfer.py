"""Trained on one corpus, asked on another: whether an engine's figures hold up on scenes from elsewhere.

Every engine is trained on all of ``train`` and asked every held-out query of ``test`` (one per support edge, as
:mod:`scenesuggest.evaluation.evaluate` asks them), with the test scene's categories mapped into the training
corpus's (:mod:`scenesuggest.corpora.crosswalk`). A query whose category is unmapped is no query: it is counted
(``unmapped_queries``, by category) and left out. Reported per engine: MRR, top-1, top-5 and orientation, over all
queries and split by whether the query's parent is one the training corpus knows (``known_parents``: mapped, or the
room) or not (``unknown_parents``: an unmapped or unlabelled parent), each engine after the first with the paired
bootstrap interval of its MRR difference from the first (resampling the test corpus's scene groups).

Like for like (``like_for_like``): each engine's in-corpus MRR per category (grouped k-fold on ``train``) weighted
by the mix of the cross-corpus queries' categories is what the engine would score on those queries if they were as
easy as its own corpus's; ``kept`` is the cross-corpus MRR over the same queries divided by it (1: nothing lost).
The in-corpus engines train on (k−1)/k of ``train`` and the cross-corpus ones on all of it, so ``kept`` leans high.
Beside it, the ceiling (``asked_corpus``): the same engine trained and asked by grouped k-fold on ``test`` itself,
its categories mapped into ``train``'s vocabulary as the cross-corpus queries are (an unmapped object is ``Unknown``
there: context, never suggested nor asked for), weighted by the same mix — what an engine that had seen scenes like
the asked ones would score on them. It ranks only the categories of ``train`` that ``test`` holds (those it has
seen), where the other figures rank all of ``train``'s, which lifts it; its engines train on (k−1)/k of ``test``,
which lowers it. It is no bound (an engine may beat it, ``of_ceiling`` > 1). ``kept`` at that ceiling far below 1
says the asked queries are hard even for an engine that has seen their corpus; ``of_ceiling`` is the cross-corpus
MRR as a share of the ceiling's.

Nothing of ``test`` reaches the cross-corpus engines' training: the two corpora must differ (by source and by scene
ids), and the symmetry periods the learned engine trains with are measured on ``train``'s models alone (``test``'s
measure its queries' orientation, looked up under their own categories). The ceiling's engines alone train on
``test`` (its other folds), by design.
"""

from __future__ import annotations

import math
from collections import Counter
from collections.abc import Callable, Iterable

import numpy as np

from ..assets.symmetry import corpus_periods
from ..corpora.corpus import Corpus
from ..corpora.crosswalk import Crosswalk, crosswalk
from ..corpora.folds import grouped_folds, similar_groups
from ..corpora.wordnet import WordNet, wordnet
from ..engines import EngineSpec
from ..errors import SceneSuggestError
from ..learning.priors import Priors
from ..scenes.scene import ROOM
from ..scenes.taxonomy import Taxonomy
from ..suggestion.held_out import DEFAULT_SCENE_TYPE, check_scene_type, held_out_queries
from ..suggestion.suggest import Engine, EngineOptions
from ..suggestion.suggestable import suggestable
from .evaluate import (
    EngineRun,
    Run,
    checked_specs,
    engine_figures,
    fitted_engine,
    measure_query,
    paired_difference,
    ranks_by_category,
    run_folds,
    summary,
)

#: How many suggestions an explained miss lists beside the true category.
EXPLAINED_TOP = 3


def evaluate_transfer(train: Corpus, test: Corpus, engines: list[EngineSpec] | None = None, seed: int = 0,
                      resamples: int = 1000, scene_type: str = DEFAULT_SCENE_TYPE, folds: int = 5,
                      like_for_like: bool = True, explain: int = 0, wn: WordNet | None = None,
                      progress: Callable[[Iterable, str], Iterable] | None = None) -> dict:
    """Train every engine of ``engines`` (default: the paper's) on ``train``, ask them ``test``'s queries; the
    JSON-ready summary (see the module). ``explain``: for each engine that explains itself, its ``explain`` worst
    misses (the largest ranks of a category it knows), with why."""
    check_scene_type(scene_type)
    progress = progress or (lambda items, label="": items)
    specs = checked_specs(engines, EngineOptions())
    check_apart(train, test)
    scene_groups = similar_groups(test.scenes)
    train_groups = similar_groups(train.scenes) if like_for_like else []  # like for like's folds alone use them
    if like_for_like:
        check_foldable(train.source, train_groups, folds)
        check_foldable(test.source, scene_groups, folds)
    walk = crosswalk(test, train, wn or wordnet())
    periods = corpus_periods(train.models.values(), progress)
    asked_periods = _AskedPeriods(corpus_periods(test.models.values(), progress), test)
    priors = Priors.fit(train.scenes, train.taxonomy)
    paper = Engine(priors, _paper_options(specs))
    paper_rule = paper.with_options(orientation="paper")
    fitted = {s.name: fitted_engine(s, priors, train.scenes, train, seed, periods, progress) for s in specs}
    asked = Corpus(test.source, [], test.models, train.taxonomy)  # test models, training vocabulary
    runs = {s.name: EngineRun() for s in specs}
    groups, categories, known_parent, queries = [], [], [], []
    unmapped, skipped = Counter(), 0
    for i, scene in enumerate(progress(test.scenes, "scenes")):
        relabelled = walk.relabel(scene)
        for query, o in held_out_queries(relabelled, train.taxonomy, scene_type):
            original = scene.objects[o.id].category
            if walk.category(original) is None:
                unmapped[original] += 1
                continue
            try:
                paper.prepare(query)
            except SceneSuggestError:  # a contact far from its parent's box: bad data, not a query
                skipped += 1
                continue
            groups.append(scene_groups[i])
            categories.append(o.category)
            parent = relabelled.objects[o.parent].category
            known_parent.append(parent == ROOM or (parent in paper.index and suggestable(parent)))
            if explain:
                queries.append((scene.id, query, o, original))
            for s in specs:
                measure_query(runs[s.name], fitted[s.name], paper_rule, query, relabelled, o, asked, asked_periods,
                              False)
    if not groups:
        raise SceneSuggestError(f"no held-out query of {test.source} maps into {train.source}'s categories",
                                field="test")
    known = np.array(known_parent, dtype=bool)
    result = {
        "train": train.source, "test": test.source, "seed": seed, "scene_type": scene_type, "queries": len(groups),
        "skipped": skipped, "unmapped_queries": sum(unmapped.values()),
        "unmapped_by_category": dict(unmapped.most_common()), "known_parent_queries": int(known.sum()),
        "crosswalk": walk.to_dict(), "engine": specs[0].name,
        "engines": _blocks(runs, specs, groups, known, resamples, seed),
    }
    if like_for_like:
        asked_home = _asked_in_corpus(test, walk, train.taxonomy, specs, folds, seed, scene_type, asked_periods,
                                      scene_groups, progress)
        _add_like_for_like(result, train, train_groups, specs, runs, categories, folds, seed, scene_type, periods,
                           asked_home, progress)
    if explain:
        result["explained_misses"] = _misses(fitted, runs, queries, explain)
    return result


def check_apart(train: Corpus, test: Corpus) -> None:
    """Refuse to call figures held out when the two corpora are one (the same source, or scenes of the same id)."""
    if train.source == test.source:
        raise SceneSuggestError(f"--train and --test are the same corpus ({train.source}): its figures would not be "
                                "held out (evaluate SOURCE runs k-fold on one corpus)", field="test")
    shared = {s.id for s in train.scenes} & {s.id for s in test.scenes}
    if shared:
        raise SceneSuggestError(f"{len(shared)} scenes of {test.source} are also in {train.source} (e.g. "
                                f"{sorted(shared)[0]!r}): its figures would not be held out", field="test")


def check_foldable(source: str, groups: list[int], folds: int) -> None:
    """Refuse like for like when a corpus has fewer groups of similar scenes (``groups``: each scene's; a scene
    without a near-copy is a group of its own) than ``folds``: a fold would be empty, and its engines would train on
    every scene for no query."""
    count = len(set(groups))
    if count < folds:
        fix = f"--folds {count} or fewer, or --no-like-for-like" if count >= 2 else "--no-like-for-like"
        raise SceneSuggestError(f"{source} has {count} group(s) of similar scenes, fewer than the {folds} folds like "
                                f"for like runs on it (give {fix})", field="folds")


def _paper_options(specs: list[EngineSpec]) -> EngineOptions:
    """The options of the paper engine the queries are checked and the baselines scored with."""
    return specs[0].config if specs[0].name == "paper" else EngineOptions()


class _AskedPeriods:
    """The asked corpus's symmetry periods, looked up under a model's own category (not the one it is mapped to)."""

    def __init__(self, periods, corpus: Corpus):
        self.periods, self.models = periods, corpus.models

    def of(self, model_id: str, category: str, footprint=None):
        model = self.models.get(model_id)
        return self.periods.of(model_id, model.category if model else "", footprint)


def _blocks(runs: dict[str, EngineRun], specs: list[EngineSpec], groups: list[int], known: np.ndarray,
            resamples: int, seed: int) -> dict[str, dict]:
    first = specs[0].name
    out = {}
    for s in specs:
        ranks = runs[s.name].ranks
        block = {**engine_figures(ranks, runs[s.name].records), "version": s.kind.version}
        for part, mask in (("known_parents", known), ("unknown_parents", ~known)):
            block[part] = summary([r for r, k in zip(ranks, mask, strict=True) if k])
        if s.name != first:
            base = runs[first].ranks
            block["vs_first"] = {"engine": first, **paired_difference(base, ranks, groups, resamples, seed)}
            if known.any():
                pick = np.flatnonzero(known)
                block["known_parents"]["vs_first"] = {
                    "engine": first, **paired_difference([base[k] for k in pick], [ranks[k] for k in pick],
                                                         [groups[k] for k in pick], resamples, seed)}
        out[s.name] = block
    return out


def _asked_in_corpus(test: Corpus, walk: Crosswalk, taxonomy: Taxonomy, specs: list[EngineSpec], folds: int,
                     seed: int, scene_type: str, periods: _AskedPeriods, groups: list[int], progress) -> Run:
    """Every engine trained and asked by grouped folds on ``test``, relabelled into the training vocabulary (an
    unmapped object ``Unknown``)."""
    relabelled = Corpus(test.source, [walk.relabel(scene, unmapped_unknown=True) for scene in test.scenes],
                        test.models, taxonomy)
    return run_folds(relabelled, grouped_folds(groups, folds, seed), _paper_options(specs), periods, progress,
                     rankings=False, specs=specs, groups=groups, seed=seed, scene_type=scene_type)


def _add_like_for_like(result: dict, train: Corpus, groups: list[int], specs: list[EngineSpec],
                       runs: dict[str, EngineRun], categories: list[str], folds: int, seed: int, scene_type: str,
                       periods, asked_home: Run, progress) -> None:
    """Each engine's in-corpus MRR per category on ``train`` (grouped folds), weighted by the cross-corpus queries'
    categories, beside its cross-corpus MRR on the same queries, and the same weighting of its in-corpus MRR on
    the asked corpus (``asked_home``, the ceiling; see the module)."""
    home = run_folds(train, grouped_folds(groups, folds, seed), _paper_options(specs), periods, progress,
                     rankings=False, specs=specs, groups=groups, seed=seed, scene_type=scene_type)
    def weighted(mrr_of: dict[str, float], picked: list[int]) -> float:
        """A per-category MRR weighted by the picked cross-corpus queries' categories."""
        return float(np.mean([mrr_of[categories[k]] for k in picked])) if picked else 0.0

    for s in specs:
        by = {c: summary(r)["mrr"] for c, r in ranks_by_category(home, s.name).items()}
        there = {c: summary(r)["mrr"] for c, r in ranks_by_category(asked_home, s.name).items()}
        ranks = runs[s.name].ranks
        pick = [k for k, c in enumerate(categories) if c in by]
        expected = weighted(by, pick)
        observed = summary([ranks[k] for k in pick])["mrr"] if pick else 0.0
        # the ceiling's folds ask the same queries (a contact too far from its parent is so in both runs); its
        # ratios are over the queries it asked, whatever happens
        topped = [k for k in pick if categories[k] in there]
        ceiling, base = weighted(there, topped), weighted(by, topped)
        below = summary([ranks[k] for k in topped])["mrr"] if topped else 0.0
        mix = Counter(categories[k] for k in pick)
        result["engines"][s.name]["like_for_like"] = {
            "in_corpus_mrr": summary(home.engines[s.name].ranks)["mrr"], "in_corpus_queries": len(home.groups),
            "folds": folds, "queries": len(pick), "reweighted_in_corpus_mrr": expected,
            "cross_corpus_mrr": observed, "kept": observed / expected if expected else 0.0,
            "asked_corpus": {"mrr": summary(asked_home.engines[s.name].ranks)["mrr"],
                             "asked_queries": len(asked_home.groups), "queries": len(topped),
                             "reweighted_mrr": ceiling, "kept": ceiling / base if base else 0.0,
                             "of_ceiling": below / ceiling if ceiling else 0.0},
            "by_category": {c: {"in_corpus_mrr": by[c], "asked_corpus_mrr": there.get(c), "queries": n}
                            for c, n in mix.most_common()}}


def _misses(fitted: dict, runs: dict[str, EngineRun], queries: list, n: int) -> dict[str, list]:
    """Per engine that explains itself: its ``n`` worst ranks of a category it knows, each with every engine's rank
    and the engine's explanation of its top suggestions and of the true category."""
    out = {}
    for name, engine in fitted.items():
        if not hasattr(engine, "explain"):
            continue
        ranks = runs[name].ranks
        order = sorted((k for k, r in enumerate(ranks) if math.isfinite(r)), key=lambda k: (-ranks[k], k))[:n]
        rows = []
        for k in order:
            scene_id, query, o, original = queries[k]
            parent = query.scene.objects[query.parent_id]
            rows.append({"scene": scene_id, "object": o.id, "category": o.category, "as_named_there": original,
                         "parent": parent.category, "parent_id": parent.id, "scene_type": query.scene_type,
                         "ranks": {e: runs[e].ranks[k] if math.isfinite(runs[e].ranks[k]) else None for e in runs},
                         "explanation": engine.explain(query, "full", EXPLAINED_TOP, [o.category])})
        out[name] = rows
    return out
