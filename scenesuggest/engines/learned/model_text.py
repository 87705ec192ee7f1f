"""A check of a LightGBM model's text before LightGBM reads it.

LightGBM reads a model's text (``Booster(model_str=…)``) trusting it: a tree whose byte size disagrees with the
header's ``tree_sizes``, a split on a feature the model does not have or a child index out of range ends the
process (an abort inside LightGBM's parallel parser, SIGABRT), which no ``except`` can catch. :func:`check_model_text`
reads the text as LightGBM's writer lays it out (``version=v4``: a header of ``key=value`` lines, then one block per
tree of exactly ``tree_sizes`` bytes, each ``Tree=k`` and its arrays, then ``end of trees``) and refuses anything
else, naming what is wrong.
"""

from __future__ import annotations

from itertools import pairwise

#: Arrays of a tree with one entry per internal node (num_leaves − 1) and per leaf (num_leaves).
INTERNAL = ("split_feature", "split_gain", "threshold", "decision_type", "left_child", "right_child")
LEAVES = ("leaf_value",)
#: Arrays written per node whose length is checked when present.
OPTIONAL_INTERNAL = ("internal_value", "internal_weight", "internal_count")
OPTIONAL_LEAVES = ("leaf_weight", "leaf_count")


def check_model_text(text: str, features: int) -> None:
    """Raise ValueError saying what is wrong unless ``text`` is a LightGBM model (text format v4, no linear trees)
    over ``features`` features whose every tree is well formed: its block of the header's size, its arrays of
    the lengths its leaves imply, splits on existing features, and children that make one tree."""
    start = text.find("\nTree=")
    if not text.startswith("tree\n") or start < 0:
        raise ValueError("not a LightGBM model's text")
    header = _pairs(text[:start].splitlines()[1:], "the header")
    if header.get("version") != "v4":
        raise ValueError(f"a LightGBM model of format {header.get('version')!r}, not v4")
    if _int(header, "max_feature_idx", "the header") != features - 1:
        raise ValueError(f"a model of {int(header['max_feature_idx']) + 1} features, not {features}")
    sizes = [_to_int(v, "tree_sizes") for v in header.get("tree_sizes", "").split()]
    at = start + 1
    for k, size in enumerate(sizes):
        if size <= 0 or at + size > len(text):
            raise ValueError(f"tree {k}: tree_sizes says {size} bytes, beyond the text")
        _check_tree(text[at:at + size], k, features)
        at += size
    if not text[at:].lstrip("\n").startswith("end of trees"):
        raise ValueError("the trees do not end where tree_sizes says")


def _check_tree(block: str, k: int, features: int) -> None:
    where = f"tree {k}"
    lines = block.splitlines()
    if not lines or lines[0] != f"Tree={k}":
        raise ValueError(f"{where}: its block does not start with 'Tree={k}' (tree_sizes disagrees with the trees)")
    fields = _pairs(lines[1:], where)
    leaves = _int(fields, "num_leaves", where)
    if leaves < 1:
        raise ValueError(f"{where}: num_leaves {leaves}")
    if fields.get("is_linear", "0") != "0":
        raise ValueError(f"{where}: a linear tree")
    arrays = {name: fields.get(name, "").split() for name in (*INTERNAL, *LEAVES, *OPTIONAL_INTERNAL,
                                                              *OPTIONAL_LEAVES)}
    for name in LEAVES:
        _length(arrays[name], leaves, name, where)
    for name in OPTIONAL_LEAVES:
        if name in fields:
            _length(arrays[name], leaves, name, where)
    if leaves == 1:
        return
    for name in (*INTERNAL, *(n for n in OPTIONAL_INTERNAL if n in fields)):
        _length(arrays[name], leaves - 1, name, where)
    for name in (*INTERNAL[1:3], *LEAVES):
        for v in arrays[name]:
            _to_float(v, f"{where}: {name}")
    split = [_to_int(v, f"{where}: split_feature") for v in arrays["split_feature"]]
    if any(not 0 <= f < features for f in split):
        raise ValueError(f"{where}: a split on a feature outside 0..{features - 1}")
    cats = _int(fields, "num_cat", where) if "num_cat" in fields else 0
    decision = [_to_int(v, f"{where}: decision_type") for v in arrays["decision_type"]]
    if cats:
        bounds = [_to_int(v, f"{where}: cat_boundaries") for v in fields.get("cat_boundaries", "").split()]
        words = fields.get("cat_threshold", "").split()
        if (len(bounds) != cats + 1 or bounds[0] != 0 or any(a > b for a, b in pairwise(bounds))
                or bounds[-1] != len(words)):
            raise ValueError(f"{where}: cat_boundaries do not index its {len(words)} cat_threshold words")
        for v in words:
            _to_int(v, f"{where}: cat_threshold")
    for node, d in enumerate(decision):
        if d & 1:  # a categorical split: its threshold indexes the categories' boundaries
            t = _to_float(arrays["threshold"][node], f"{where}: threshold")
            if not (t.is_integer() and 0 <= t < cats):
                raise ValueError(f"{where}: a categorical split on category set {t} of {cats}")
    seen_nodes, seen_leaves = [False] * (leaves - 1), [False] * leaves
    for side in ("left_child", "right_child"):
        for child in (_to_int(v, f"{where}: {side}") for v in arrays[side]):
            if child >= 0:
                if not 0 < child < leaves - 1 or seen_nodes[child]:
                    raise ValueError(f"{where}: {side} names node {child} twice or out of range")
                seen_nodes[child] = True
            else:
                leaf = ~child
                if leaf >= leaves or seen_leaves[leaf]:
                    raise ValueError(f"{where}: {side} names leaf {leaf} twice or out of range")
                seen_leaves[leaf] = True
    if not all(seen_nodes[1:]) or not all(seen_leaves):
        raise ValueError(f"{where}: its children do not make one tree")


def _pairs(lines: list[str], where: str) -> dict[str, str]:
    out = {}
    for line in lines:
        if not line:
            continue
        key, eq, value = line.partition("=")
        if not eq:
            raise ValueError(f"{where}: a line that is not key=value")
        out[key] = value
    return out


def _int(fields: dict[str, str], key: str, where: str) -> int:
    if key not in fields:
        raise ValueError(f"{where}: no {key}")
    return _to_int(fields[key], f"{where}: {key}")


def _to_int(value: str, where: str) -> int:
    try:
        return int(value)
    except ValueError:
        raise ValueError(f"{where}: {value[:20]!r} is not an integer") from None


def _to_float(value: str, where: str) -> float:
    try:
        return float(value)
    except ValueError:
        raise ValueError(f"{where}: {value[:20]!r} is not a number") from None


def _length(values: list[str], n: int, name: str, where: str) -> None:
    if len(values) != n:
        raise ValueError(f"{where}: {len(values)} {name} for {n}")
