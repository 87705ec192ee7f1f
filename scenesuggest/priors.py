"""The contextual priors of SceneSuggest, learned from a corpus, as plain arrays.

* occurrence — per (parent, scene type): for each child category C the histogram of how many children of
  C each parent instance carries, giving ``P(|C on p| > k)``;
* support surface ``P_sup(t | C)`` and attachment face ``P_att(f | C, t)`` — counts;
* relative position — 2-D Gaussian KDEs of the offsets δ (metres, :mod:`.observations`) per
  (C, C_ref, scene type, relation, surface type), bandwidth by Scott's rule (at least 5 cm);
* relative orientation — wrapped 36-bin (10°) histograms of θ for the same keys, smoothed with a
  (1, 2, 1) kernel.

Both position densities and orientation histograms are divided by their peak, so each is a relative
likelihood in [0, 1] and comparable with the probabilities of the occurrence term.

Back-off, as in the paper, is by category: statistics are kept for *entities* — a category itself
(``Chair``) and, for categories with subcategories, its whole subtree (``Chair/*``). A category with
fewer than 5 instances reads the statistics of the first ancestor subtree that has 5 (:meth:`Priors.
stat_entity`). Statistics keyed by scene type climb the taxonomy within the query's scene type first
(a chest of drawers in a bedroom reads the bedroom statistics of all chests of drawers) and only then
use all scene types (``*``) (:meth:`Priors.keyed_entity`); what is borrowed from other scene types only
counts for categories seen in the query's scene type at least once, so that what never happens in
bedrooms is not brought in from kitchens (:mod:`.suggest`). When nothing is observed the engine falls
back to geometry.
"""

from __future__ import annotations

import json
import math
from collections import Counter, defaultdict
from collections.abc import Callable, Iterable
from pathlib import Path

import numpy as np

from . import frames
from .errors import SceneSuggestError
from .observations import RELATIONS, corpus_observations
from .scene import SURFACE_TYPES, Scene
from .taxonomy import MIN_OBSERVATIONS, Taxonomy

FORMAT = "scenesuggest-priors"
VERSION = 1
ANY = "*"
K_MAX = 8
BINS = 36
MIN_BANDWIDTH_M = 0.05
#: Peak normalisers are evaluated at up to this many sample points per KDE; KDEs of up to SMALL_SEGMENT
#: samples are normalised together, exactly.
PEAK_POINTS = 512
SMALL_SEGMENT = 24
FACES = frames.FACES


def _subtree(category: str) -> str:
    return f"{category}/*"


class Priors:
    """Learned state (arrays) plus the lookups the engine needs. Build with :meth:`fit` or :meth:`load`."""

    def __init__(self, arrays: dict[str, np.ndarray], meta: dict):
        self.meta = meta
        self.arrays = arrays
        self.categories: list[str] = meta["categories"]
        self.entities: list[str] = meta["entities"]
        self.scene_types: list[str] = meta["scene_types"]
        self.model_ids: list[str] = meta["model_ids"]
        self.taxonomy = Taxonomy(meta["taxonomy"])
        self.category_index = {c: i for i, c in enumerate(self.categories)}
        self.entity_index = {e: i for i, e in enumerate(self.entities)}
        self.scene_index = {s: i for i, s in enumerate(self.scene_types)}
        for name, value in arrays.items():
            setattr(self, name, value)
        self._groups = {tuple(int(v) for v in key): g for g, key in enumerate(self.group_keys)}
        self._occ_starts = np.searchsorted(self.occ_key, np.arange(len(self.entities) * len(self.scene_types) + 1))
        self._group_seg_starts = np.searchsorted(self.seg_group, np.arange(len(self.group_keys) + 1))

    # --- vocabulary and back-off -------------------------------------------------------------------------
    def entity_chain(self, category: str) -> list[int]:
        """Entities from specific to general: the category, its subtree, then its ancestors' subtrees."""
        chain = []
        if category in self.entity_index:
            chain.append(self.entity_index[category])
        for c in [category, *self.taxonomy.ancestors(category)]:
            e = self.entity_index.get(_subtree(c))
            if e is not None:
                chain.append(e)
        return chain

    # --- construction --------------------------------------------------------------------------------------
    @classmethod
    def fit(cls, scenes: Iterable[Scene], taxonomy: Taxonomy | None = None,
            progress: Callable[[Iterable, str], Iterable] | None = None) -> Priors:
        """Learn every prior from ``scenes`` (world frame) with ``taxonomy`` for back-off."""
        return _fit(list(scenes), taxonomy or Taxonomy(), progress or (lambda items, label="": items))

    # --- persistence ---------------------------------------------------------------------------------------
    def save(self, path: str | Path) -> Path:
        """Write one ``.npz`` file; saving what was loaded reproduces the file byte for byte."""
        path = Path(path)
        payload = dict(self.arrays)
        payload["meta"] = np.frombuffer(json.dumps(self.meta, sort_keys=True).encode(), dtype=np.uint8)
        with path.open("wb") as f:
            np.savez_compressed(f, **{k: payload[k] for k in sorted(payload)})
        return path

    @classmethod
    def load(cls, path: str | Path) -> Priors:
        path = Path(path)
        try:
            with np.load(path, allow_pickle=False) as data:
                arrays = {k: data[k] for k in data.files}
        except (OSError, ValueError) as e:
            raise SceneSuggestError(f"cannot read priors: {e}", file=str(path)) from None
        if "meta" not in arrays:
            raise SceneSuggestError("not a priors file (no metadata)", file=str(path), field="meta")
        try:
            meta = json.loads(arrays.pop("meta").tobytes().decode())
        except (UnicodeDecodeError, ValueError):
            raise SceneSuggestError("not a priors file (bad metadata)", file=str(path), field="meta") from None
        if meta.get("format") != FORMAT:
            raise SceneSuggestError("not a priors file", file=str(path), field="format")
        if meta.get("version") != VERSION:
            raise SceneSuggestError(f"priors file has version {meta.get('version')!r}, this engine reads "
                                    f"version {VERSION}: retrain with 'scenesuggest priors train'",
                                    file=str(path), field="version")
        return cls(arrays, meta)

    # --- lookups -------------------------------------------------------------------------------------------
    def stat_entity(self, category: str, backoff: bool = True) -> int | None:
        """The entity whose statistics stand for ``category``: the category itself when it has at least 5
        instances, else the first ancestor subtree that has (else the best observed; None if unknown)."""
        chain = self.entity_chain(category)
        if not chain:
            return None
        if not backoff:
            return chain[0]
        counts = [float(self.occ_parent_n[e, -1]) for e in chain]
        for e, n in zip(chain, counts, strict=True):
            if n >= MIN_OBSERVATIONS:
                return e
        return chain[int(np.argmax(counts))]

    def keyed_entity(self, category: str, scene_type: str | None, backoff: bool = True) -> tuple[int, int] | None:
        """(entity, scene index) for statistics keyed by scene type: the first of the category's chain with
        at least 5 instances in the scene type; failing that, its statistics entity over all scene types.
        Without back-off: the category itself in the scene type (all types if the type is unknown)."""
        chain = self.entity_chain(category)
        if not chain:
            return None
        any_s = len(self.scene_types) - 1
        s = self.scene_index.get(scene_type, any_s) if scene_type not in (None, ANY) else any_s
        if not backoff:
            return chain[0], s
        counts = self.occ_parent_n[chain, s]
        for e, n in zip(chain, counts, strict=True):
            if n >= MIN_OBSERVATIONS:
                return e, s
        return self.stat_entity(category), any_s

    def occurrence_key(self, parent_category: str, scene_type: str | None, backoff: bool = True) -> int | None:
        """The (parent entity, scene type) row block to read P(|C on p| > k) from; None for a parent
        category never seen."""
        key = self.keyed_entity(parent_category, scene_type, backoff)
        if key is None or self.occ_parent_n[key] == 0:
            return None
        return key[0] * len(self.scene_types) + key[1]

    def occurrence_rows(self, key: int) -> tuple[np.ndarray, np.ndarray]:
        """(child entities, P(>k) rows of length K_MAX+1) observed under an occurrence key."""
        a, b = self._occ_starts[key], self._occ_starts[key + 1]
        return self.occ_child[a:b], self.occ_pgt[a:b]

    def group_for(self, ref_category: str, scene_type: str | None, relation: str, surface_type: str,
                  backoff: bool = True) -> int | None:
        """The pair-prior group of a reference (its entity, scene type, relation, surface type)."""
        key = self.keyed_entity(ref_category, scene_type, backoff)
        if key is None:
            return None
        return self._groups.get((*key, RELATIONS.index(relation), SURFACE_TYPES.index(surface_type)))

    def segments(self, group: int) -> tuple[np.ndarray, np.ndarray]:
        """(child entities, segment indices) of a pair-prior group, sorted by child entity."""
        a, b = self._group_seg_starts[group], self._group_seg_starts[group + 1]
        return self.seg_child[a:b], np.arange(a, b)

    def describe(self) -> dict:
        return {"scenes": self.meta["scenes"], "supports": self.meta["supports"], "pairs": int(len(self.pair_xy)),
                "categories": len(self.categories), "candidates": int(len(self.candidate_categories)),
                "entities": len(self.entities), "groups": int(len(self.group_keys)),
                "segments": int(len(self.seg_group)), "scene_types": self.scene_types[:-1]}


# --- fitting -----------------------------------------------------------------------------------------------
def _fit(scenes: list[Scene], taxonomy: Taxonomy, progress) -> Priors:
    present = sorted({o.category for s in scenes for o in s})
    categories = sorted(set(present) | {a for c in present for a in taxonomy.ancestors(c)})
    parents = {c: taxonomy.parent(c) for c in categories if taxonomy.parent(c) in set(categories)}
    tax = Taxonomy(parents)
    has_children = set(parents.values())
    entities = list(categories) + [_subtree(c) for c in categories if c in has_children]
    entity_index = {e: i for i, e in enumerate(entities)}
    expand = {c: [entity_index[c]] + [entity_index[_subtree(x)] for x in [c, *tax.ancestors(c)]
                                      if _subtree(x) in entity_index] for c in categories}
    scene_types = sorted({s.scene_type for s in scenes} - {ANY}) + [ANY]
    s_index = {s: i for i, s in enumerate(scene_types)}
    n_e, n_s, any_s = len(entities), len(scene_types), len(scene_types) - 1

    # occurrence: child counts per parent instance
    parent_n = np.zeros((n_e, n_s), dtype=np.float64)
    hist: dict[tuple[int, int], np.ndarray] = {}
    for scene in progress(scenes, "counting children"):
        children = defaultdict(Counter)
        for o in scene:
            if o.parent is not None:
                children[o.parent].update(expand[o.category])
        for p in scene:
            keys = [(e, s) for e in expand[p.category] for s in {s_index[scene.scene_type], any_s}]
            for e, s in keys:
                parent_n[e, s] += 1
                for child, count in children[p.id].items():
                    h = hist.setdefault((e * n_s + s, child), np.zeros(K_MAX + 1))
                    h[min(count, K_MAX)] += 1
    occ_items = sorted(hist.items())
    occ_key = np.array([k for (k, _), _ in occ_items], dtype=np.int32)
    occ_child = np.array([c for (_, c), _ in occ_items], dtype=np.int32)
    occ_pgt = np.zeros((len(occ_items), K_MAX + 1), dtype=np.float32)
    for i, ((key, _), h) in enumerate(occ_items):
        n = parent_n[key // n_s, key % n_s]
        occ_pgt[i] = (h[::-1].cumsum()[::-1] - h) / n  # P(count > k) for k = 0..K_MAX

    supports, pairs = corpus_observations(scenes)
    sup_counts = np.zeros((n_e, len(SURFACE_TYPES)), dtype=np.float32)
    att_counts = np.zeros((n_e, len(SURFACE_TYPES), len(FACES)), dtype=np.float32)
    model_counts: Counter = Counter()
    model_info: dict[str, tuple[str, tuple]] = {}
    for sup in supports:
        t, f = SURFACE_TYPES.index(sup.surface_type), FACES.index(sup.face)
        for e in expand[sup.category]:
            sup_counts[e, t] += 1
            att_counts[e, t, f] += 1
        model_counts[sup.model_id] += 1
        model_info[sup.model_id] = (sup.category, sup.size)

    arrays = _pair_arrays(pairs, expand, s_index, any_s, progress)
    model_ids = sorted(model_counts, key=lambda m: (model_info[m][0], -model_counts[m], m))
    c_index = {c: i for i, c in enumerate(categories)}
    candidate_categories = np.array(sorted({c_index[model_info[m][0]] for m in model_ids}), dtype=np.int32)
    arrays.update(
        occ_parent_n=parent_n.astype(np.float32), occ_key=occ_key, occ_child=occ_child, occ_pgt=occ_pgt,
        sup_counts=sup_counts, att_counts=att_counts,
        model_category=np.array([c_index[model_info[m][0]] for m in model_ids], dtype=np.int32),
        model_size=np.array([model_info[m][1] for m in model_ids], dtype=np.float32),
        model_count=np.array([model_counts[m] for m in model_ids], dtype=np.int32),
        candidate_categories=candidate_categories,
    )
    meta = {"format": FORMAT, "version": VERSION, "categories": categories, "entities": entities,
            "scene_types": scene_types, "model_ids": model_ids, "taxonomy": tax.to_dict(),
            "scenes": len(scenes), "scene_ids": sorted(s.id for s in scenes), "supports": len(supports),
            "k_max": K_MAX, "bins": BINS, "min_observations": MIN_OBSERVATIONS}
    return Priors(arrays, meta)


def _pair_arrays(pairs, expand, s_index, any_s, progress) -> dict[str, np.ndarray]:
    """Expand pair observations over entities and scene keys, group them and fit KDEs and histograms."""
    group_of: dict[tuple[int, int, int, int], int] = {}
    rows_group, rows_child, rows_xy, rows_theta = [], [], [], []
    for p in progress(pairs, "expanding pairs"):
        r, t = RELATIONS.index(p.relation), SURFACE_TYPES.index(p.surface_type)
        for e_ref in expand[p.ref_category]:
            for s in {s_index[p.scene_type], any_s}:
                g = group_of.setdefault((e_ref, s, r, t), len(group_of))
                for e_child in expand[p.category]:
                    rows_group.append(g)
                    rows_child.append(e_child)
                    rows_xy.append(p.offset)
                    rows_theta.append(p.theta)
    keys = sorted(group_of)  # renumber groups in key order so files are deterministic
    renumber = np.empty(len(keys), dtype=np.int32)
    for new, key in enumerate(keys):
        renumber[group_of[key]] = new
    group = renumber[np.array(rows_group, dtype=np.int64)] if rows_group else np.zeros(0, np.int32)
    child = np.array(rows_child, dtype=np.int32)
    xy = np.array(rows_xy, dtype=np.float32).reshape(-1, 2)
    theta = np.array(rows_theta, dtype=np.float32)
    order = np.lexsort((theta, xy[:, 1], xy[:, 0], child, group))
    group, child, xy, theta = group[order], child[order], xy[order], theta[order]
    seg_id = np.r_[0, np.cumsum((np.diff(group) != 0) | (np.diff(child) != 0))] if len(group) else group
    starts = np.flatnonzero(np.r_[True, np.diff(seg_id) != 0]) if len(group) else np.zeros(0, np.int64)
    counts = np.diff(np.r_[starts, len(group)])
    bandwidth = _bandwidths(xy.astype(np.float64), starts, counts)
    peaks = np.zeros(len(starts))
    small = counts <= SMALL_SEGMENT
    peaks[small] = _small_peaks(xy, starts[small], counts[small], bandwidth[small])
    for i in progress(np.flatnonzero(~small), "fitting densities"):
        peaks[i] = _peak(xy[starts[i]:starts[i] + counts[i]].astype(np.float64), bandwidth[i])
    return {
        "group_keys": np.array(keys, dtype=np.int32).reshape(-1, 4),
        "seg_group": group[starts].astype(np.int32), "seg_child": child[starts].astype(np.int32),
        "seg_start": starts.astype(np.int64), "seg_count": counts.astype(np.int32),
        "seg_bandwidth": bandwidth.astype(np.float32), "seg_weight": (1.0 / peaks).astype(np.float32),
        "seg_hist": orientation_histograms(theta, seg_id, len(starts)), "pair_xy": xy,
    }


def _bandwidths(xy: np.ndarray, starts: np.ndarray, counts: np.ndarray) -> np.ndarray:
    """Scott's rule per segment (σ · n^(−1/6) per axis), at least MIN_BANDWIDTH_M."""
    if not len(starts):
        return np.zeros((0, 2))
    n = counts[:, None].astype(np.float64)
    mean = np.add.reduceat(xy, starts, axis=0) / n
    var = np.maximum(np.add.reduceat(xy ** 2, starts, axis=0) / n - mean ** 2, 0.0)
    return np.maximum(np.sqrt(var) * n ** (-1 / 6), MIN_BANDWIDTH_M)


def _small_peaks(xy: np.ndarray, starts: np.ndarray, counts: np.ndarray, bandwidth: np.ndarray) -> np.ndarray:
    """Peaks of many small KDEs at once: samples padded to SMALL_SEGMENT, all pairs evaluated together."""
    out = np.zeros(len(starts))
    for lo in range(0, len(starts), 4096):
        st, ct, bw = starts[lo:lo + 4096], counts[lo:lo + 4096], bandwidth[lo:lo + 4096]
        offsets = np.arange(SMALL_SEGMENT)
        valid = offsets[None, :] < ct[:, None]
        idx = np.where(valid, st[:, None] + offsets[None, :], st[:, None])
        pts = xy[idx].astype(np.float64) / bw[:, None, :]
        d2 = ((pts[:, :, None, :] - pts[:, None, :, :]) ** 2).sum(axis=3)
        k = np.exp(-0.5 * d2) * valid[:, None, :]
        out[lo:lo + 4096] = np.where(valid, k.sum(axis=2), 0.0).max(axis=1)
    return out


def _peak(points: np.ndarray, bandwidth: np.ndarray) -> float:
    """The largest value of Σ exp(−q/2) over the sample points (all of them for small samples; for large ones
    the most repeated points and an even spread of the rest, which is where a KDE's peak lies)."""
    unique, weight = np.unique(points, axis=0, return_counts=True)
    if len(unique) <= PEAK_POINTS:
        probe = unique
    else:
        busiest = unique[np.argsort(-weight, kind="stable")[: PEAK_POINTS // 2]]
        spread = unique[:: max(1, len(unique) // (PEAK_POINTS // 2))]
        probe = np.vstack([busiest, spread])
    best = 0.0
    for chunk in np.array_split(probe, max(1, len(probe) // 128)):
        d = (chunk[:, None, :] - unique[None, :, :]) / bandwidth
        best = max(best, float((np.exp(-0.5 * (d ** 2).sum(axis=2)) @ weight).max()))
    return best


def orientation_histograms(theta: np.ndarray, segment: np.ndarray, n_segments: int) -> np.ndarray:
    """:func:`orientation_histogram` of every segment at once (``segment`` gives each angle's segment)."""
    theta = np.asarray(theta, dtype=np.float64)
    ok = np.isfinite(theta)
    bins = np.round(theta[ok] / (2 * math.pi / BINS)).astype(np.int64) % BINS
    h = np.bincount(segment[ok] * BINS + bins, minlength=n_segments * BINS).reshape(n_segments, BINS).astype(float)
    h = (np.roll(h, 1, axis=1) + 2 * h + np.roll(h, -1, axis=1)) / 4
    peak = h.max(axis=1, keepdims=True)
    return np.where(peak > 0, h / np.where(peak > 0, peak, 1.0), 1.0).astype(np.float32)


def orientation_histogram(theta: np.ndarray) -> np.ndarray:
    """Wrapped 36-bin histogram of angles (radians), bins centred on multiples of 10°, smoothed with a
    (1, 2, 1)/4 kernel and divided by its peak; flat (all ones) when no angle is defined."""
    theta = np.asarray(theta, dtype=np.float64)
    theta = theta[np.isfinite(theta)]
    if not len(theta):
        return np.ones(BINS, dtype=np.float32)
    bins = np.round(theta / (2 * math.pi / BINS)).astype(int) % BINS
    h = np.bincount(bins, minlength=BINS).astype(np.float64)
    h = (np.roll(h, 1) + 2 * h + np.roll(h, -1)) / 4
    return (h / h.max()).astype(np.float32)

