"""Held-out folds by scene, with near-copies of a scene kept in the same fold.

Many corpora hold variants of one arrangement (half of the Stanford scenes share at least half of their
supported objects' models with another scene). Testing on a variant of a training scene measures memory, not
generalisation, so :func:`similar_groups` joins such scenes, and :func:`grouped_folds` never splits a group.

The similarity rule: scene A is a near-copy of scene B when at least half of A's supported objects either
(a) use a *distinctive* model that B also uses (counted with multiplicity; a model is distinctive when at most
10% of the corpus's scenes, and at least 2, use it — so the per-type models of AI2-THOR, which every kitchen
shares, do not count), or (b) have an object of the same category in B within 30 cm of the same place (world
frame, bounding-box centres). Near-copies join in either direction, transitively.
"""

from __future__ import annotations

from collections import Counter

import numpy as np

from .scene import Scene

SHARE = 0.5
DISTINCTIVE_SCENES = 0.10
SAME_PLACE_M = 0.3


def _supported(scene: Scene):
    return [o for o in scene if o.parent is not None]


def similarity(scenes: list[Scene]) -> np.ndarray:
    """(n, n) matrix: the share of scene i's supported objects that scene j shares by the rule above."""
    n = len(scenes)
    scene_freq = Counter(m for s in scenes for m in {o.model_id for o in _supported(s)})
    limit = max(2.0, DISTINCTIVE_SCENES * n)
    models = [Counter(o.model_id for o in _supported(s) if scene_freq[o.model_id] <= limit) for s in scenes]
    boxes = []
    for s in scenes:
        objects = _supported(s)
        centres = np.array([sum(o.world_bbox()) / 2 for o in objects]).reshape(-1, 3)
        boxes.append((np.array([o.category for o in objects]), centres, [o.model_id for o in objects]))
    share = np.zeros((n, n))
    for i in range(n):
        cats_i, centres_i, models_i = boxes[i]
        if not len(cats_i):
            continue
        for j in range(n):
            if i == j:
                continue
            cats_j, centres_j, _ = boxes[j]
            by_model = Counter(models[i]) & models[j]
            # (a): objects whose distinctive model B also uses, up to B's count of it
            taken = Counter()
            hit = np.zeros(len(cats_i), dtype=bool)
            for k, m in enumerate(models_i):
                if taken[m] < by_model.get(m, 0):
                    taken[m] += 1
                    hit[k] = True
            if len(cats_j):  # (b): same category near the same place
                d = np.linalg.norm(centres_i[:, None] - centres_j[None], axis=2)
                hit |= ((cats_i[:, None] == cats_j[None]) & (d < SAME_PLACE_M)).any(axis=1)
            share[i, j] = hit.mean()
    return share


def similar_groups(scenes: list[Scene]) -> list[int]:
    """A group number per scene: near-copies (see the module docstring) share one."""
    share = similarity(scenes)
    parent = list(range(len(scenes)))

    def root(x: int) -> int:
        while parent[x] != x:
            parent[x] = parent[parent[x]]
            x = parent[x]
        return x

    for i, j in zip(*np.nonzero(np.maximum(share, share.T) >= SHARE), strict=True):
        parent[root(int(i))] = root(int(j))
    roots = {r: g for g, r in enumerate(dict.fromkeys(root(i) for i in range(len(scenes))))}
    return [roots[root(i)] for i in range(len(scenes))]


def folds_of(n_scenes: int, k: int, seed: int) -> list[np.ndarray]:
    """Scene indices in ``k`` folds of near-equal size, shuffled by ``seed`` (every scene on its own)."""
    order = np.random.default_rng(seed).permutation(n_scenes)
    return [np.sort(f) for f in np.array_split(order, k)]


def grouped_folds(groups: list[int], k: int, seed: int) -> list[np.ndarray]:
    """Scene indices in ``k`` folds that never split a group: groups in an order shuffled by ``seed``, the
    largest first, each into the fold with the fewest scenes so far."""
    members: dict[int, list[int]] = {}
    for i, g in enumerate(groups):
        members.setdefault(g, []).append(i)
    ids = list(members)
    order = np.random.default_rng(seed).permutation(len(ids))
    shuffled = [ids[i] for i in order]
    shuffled.sort(key=lambda g: -len(members[g]))  # stable: ties keep the shuffled order
    folds: list[list[int]] = [[] for _ in range(k)]
    for g in shuffled:
        smallest = min(range(k), key=lambda f: (len(folds[f]), f))
        folds[smallest] += members[g]
    return [np.array(sorted(f), dtype=int) for f in folds]
