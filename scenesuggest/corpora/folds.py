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

from ..scenes.scene import Scene

SHARE = 0.5
DISTINCTIVE_SCENES = 0.10
SAME_PLACE_M = 0.3


def _supported(scene: Scene):
    return [o for o in scene if o.parent is not None]


def similarity(scenes: list[Scene]) -> np.ndarray:
    """(n, n) matrix: the share of scene i's supported objects that scene j shares by the rule above."""
    n = len(scenes)
    objects = [_supported(s) for s in scenes]
    scene_freq = Counter(m for objs in objects for m in {o.model_id for o in objs})
    limit = max(2.0, DISTINCTIVE_SCENES * n)
    category_id: dict[str, int] = {}
    cats = [np.array([category_id.setdefault(o.category, len(category_id)) for o in objs], dtype=np.int64)
            for objs in objects]
    centres = [np.array([o.centre() for o in objs]).reshape(-1, 3) for objs in objects]
    by_category: dict[int, tuple[list[int], list[np.ndarray]]] = {}
    for j, (c, x) in enumerate(zip(cats, centres, strict=True)):
        for cat, centre in zip(c.tolist(), x, strict=True):
            entry = by_category.setdefault(cat, ([], []))
            entry[0].append(j)
            entry[1].append(centre)
    placed = {cat: (np.array(js), np.array(xs)) for cat, (js, xs) in by_category.items()}
    users: dict[str, set[int]] = {}
    for j, objs in enumerate(objects):
        for o in objs:
            if scene_freq[o.model_id] <= limit:
                users.setdefault(o.model_id, set()).add(j)
    models = [Counter(o.model_id for o in objs if scene_freq[o.model_id] <= limit) for objs in objects]
    share = np.zeros((n, n))
    for i in range(n):
        k = len(cats[i])
        if not k:
            continue
        # (b): an object of the same category within SAME_PLACE_M, in each other scene at once
        hit = np.zeros((k, n), dtype=bool)
        for row, (cat, centre) in enumerate(zip(cats[i].tolist(), centres[i], strict=True)):
            js, xs = placed[cat]
            hit[row, js[np.linalg.norm(xs - centre, axis=1) < SAME_PLACE_M]] = True
        # (a): objects whose distinctive model scene j also uses, up to j's count of it
        for j in set().union(*(users[m] for m in models[i])) if models[i] else ():
            taken: Counter = Counter()
            for row, o in enumerate(objects[i]):
                m = o.model_id
                if taken[m] < min(models[i][m], models[j].get(m, 0)):
                    taken[m] += 1
                    hit[row, j] = True
        share[i] = hit.mean(axis=0)
        share[i, i] = 0.0
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
