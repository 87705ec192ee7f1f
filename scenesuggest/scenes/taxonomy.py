"""The category taxonomy used for back-off: each category names at most one parent.

Categories are the finest names of coarse→fine paths (``Chair/OfficeChair`` → category ``OfficeChair``
with parent ``Chair``). When a statistic of a category has too few observations, the engine uses its
parent's instead: the priors walk :meth:`Taxonomy.ancestors` (``Priors.entity_chain``).
"""

from __future__ import annotations

import json
from collections import Counter, defaultdict
from collections.abc import Iterable
from importlib import resources
from pathlib import Path

from ..errors import SceneSuggestError

#: The paper's threshold: fewer observations than this → use the taxonomy parent's statistics.
MIN_OBSERVATIONS = 5


class Taxonomy:
    """A forest of categories (``parents``: category → parent category)."""

    def __init__(self, parents: dict[str, str] | None = None):
        self.parents: dict[str, str] = dict(parents or {})
        self._check_acyclic()

    def _check_acyclic(self) -> None:
        for start in self.parents:
            seen = {start}
            node = self.parents.get(start)
            while node is not None:
                if node in seen:
                    raise SceneSuggestError(f"taxonomy cycle through {node!r}")
                seen.add(node)
                node = self.parents.get(node)

    @classmethod
    def from_paths(cls, paths: Iterable[Iterable[str]]) -> Taxonomy:
        """Build from coarse→fine category paths; a category seen under several parents keeps the most
        frequent one (ties: alphabetical), and an edge that would close a cycle is dropped."""
        votes: dict[str, Counter] = defaultdict(Counter)
        for path in paths:
            path = list(path)
            for coarse, fine in zip(path, path[1:], strict=False):
                if coarse != fine:
                    votes[fine][coarse] += 1
        parents: dict[str, str] = {}
        for fine in sorted(votes, key=lambda c: -sum(votes[c].values())):
            for coarse, _ in sorted(votes[fine].items(), key=lambda kv: (-kv[1], kv[0])):
                if fine not in _ancestors(parents, coarse) | {coarse}:
                    parents[fine] = coarse
                    break
        return cls(parents)

    def parent(self, category: str) -> str | None:
        return self.parents.get(category)

    def ancestors(self, category: str) -> list[str]:
        """Parents from nearest to farthest (not including ``category``)."""
        out, node = [], self.parents.get(category)
        while node is not None:
            out.append(node)
            node = self.parents.get(node)
        return out

    def path(self, category: str) -> list[str]:
        """Coarse→fine path ending in ``category``."""
        return list(reversed(self.ancestors(category))) + [category]

    def to_dict(self) -> dict[str, str]:
        return dict(sorted(self.parents.items()))

    def save(self, path: str | Path) -> None:
        Path(path).write_text(json.dumps({"parents": self.to_dict()}, indent=1) + "\n", encoding="utf-8")

    @classmethod
    def load(cls, path: str | Path) -> Taxonomy:
        try:
            doc = json.loads(Path(path).read_text(encoding="utf-8"))
        except (OSError, ValueError) as e:
            raise SceneSuggestError(f"cannot read taxonomy: {e}", file=str(path)) from None
        parents = doc.get("parents") if isinstance(doc, dict) else None
        if not isinstance(parents, dict) or not all(
                isinstance(k, str) and isinstance(v, str) for k, v in parents.items()):
            raise SceneSuggestError("expected {\"parents\": {category: parent}}", file=str(path),
                                    field="parents")
        return cls(parents)


def _ancestors(parents: dict[str, str], category: str) -> set[str]:
    out, node = set(), parents.get(category)
    while node is not None and node not in out:
        out.add(node)
        node = parents.get(node)
    return out


def ai2thor_taxonomy() -> Taxonomy:
    """The curated taxonomy of AI2-THOR object types, shipped as package data."""
    text = resources.files("scenesuggest").joinpath("data/ai2thor_taxonomy.json").read_text(encoding="utf-8")
    return Taxonomy(json.loads(text)["parents"])
