"""The engine's vectorised scorer computes what the straightforward per-(reference, category) scorer computes.

The yardstick (benchmarks/naive_scorer.py) evaluates one scipy gaussian_kde per reference and category with the
engine's bandwidths and normalisation, and sums the learned orientation evidence bin by bin. On 50 held-out
Stanford queries every candidate's total score, and the heading scores of the ten best, agree to rtol 1e-9.
"""

import numpy as np
import pytest
from naive_scorer import NaiveScorer

from scenesuggest.learning.orientation import KINDS
from scenesuggest.learning.priors import Priors
from scenesuggest.suggestion import headings
from scenesuggest.suggestion.suggest import ContextQuery, Engine


@pytest.fixture(scope="module")
def queries_and_engine(stanford):
    held = {s.id for s in stanford.scenes[::9]}
    engine = Engine(Priors.fit([s for s in stanford.scenes if s.id not in held], stanford.taxonomy))
    rng = np.random.default_rng(7)
    edges = [(s, o) for s in stanford.scenes if s.id in held for o in s if o.parent is not None]
    picks = rng.choice(len(edges), size=50, replace=False)
    queries = [ContextQuery(edges[i][0].without(edges[i][1].id), edges[i][1].parent, edges[i][1].contact_point,
                            edges[i][1].contact_normal) for i in picks]
    return queries, engine


def test_total_scores_match_the_naive_scorer(queries_and_engine):
    queries, engine = queries_and_engine
    naive = NaiveScorer(engine)
    scored = 0
    for q in queries:
        fast = engine.score(q).total
        slow = naive.scores(q)
        np.testing.assert_allclose(fast, slow, rtol=1e-9, atol=1e-300)
        scored += int(np.count_nonzero(fast) > 10)
    assert scored >= 40  # real rankings, not rows of zeros


def test_heading_scores_match_the_naive_scorer(queries_and_engine):
    queries, engine = queries_and_engine
    naive = NaiveScorer(engine)
    exercised = dict.fromkeys(KINDS, 0)
    for q in queries:
        scores = engine.score(q)
        top = np.argsort(-scores.total, kind="stable")[:10]
        faces = engine.face_indices(scores.prepared, "full", top)
        fast = engine.heading_scores(scores, top, faces)
        evidence = headings.evidence(engine, scores.prepared, top, faces)
        for row, (i, face) in enumerate(zip(top, faces, strict=True)):
            np.testing.assert_allclose(fast[row], naive.heading_scores(q, int(i), int(face)), rtol=1e-9, atol=1e-12)
            for k, kind in enumerate(KINDS):
                exercised[kind] += int(np.ptp(evidence[row, k]) > 0)
    # every kind of evidence was compared, walls and bearings included, not flat lines
    assert min(exercised.values()) >= 20, exercised
