"""Keyword search over the model library: SQLite FTS5 with BM25 ranking.

Indexed fields: name, tags, category path (camel case split into words: ``OfficeChair`` → ``office
chair``) and description. Words are stemmed (Porter), the last word of a query matches as a prefix so
that results appear while typing, and all words must match; when that finds nothing, any word may.
"""

from __future__ import annotations

import re
import sqlite3
import threading
from collections.abc import Iterable
from dataclasses import asdict, dataclass

from .index import ModelInfo

#: BM25 column weights: name, tags, category, description.
WEIGHTS = (4.0, 2.0, 6.0, 1.0)
_WORD = re.compile(r"[^\W_]+", re.UNICODE)
_CAMEL = re.compile(r"(?<=[a-z0-9])(?=[A-Z])|(?<=[A-Z])(?=[A-Z][a-z])")


@dataclass(frozen=True)
class SearchHit:
    model_id: str
    category: str
    name: str
    score: float  # BM25, higher is better

    def to_dict(self) -> dict:
        return asdict(self)


def split_camel(text: str) -> str:
    """``"OfficeChair"`` → ``"Office Chair"``; ``"TVStand"`` → ``"TV Stand"``."""
    return _CAMEL.sub(" ", text)


def fts_query(text: str, *, any_word: bool = False) -> str | None:
    """An FTS5 MATCH expression for user text (quoted words, last one as a prefix), or None if empty."""
    words = _WORD.findall(text.lower())
    if not words:
        return None
    terms = [f'"{w}"' for w in words[:-1]] + [f'"{words[-1]}"*']
    return (" OR " if any_word else " ").join(terms)


class SearchIndex:
    """An in-memory (or file) FTS5 index of model metadata; safe to query from several threads."""

    def __init__(self, path: str = ":memory:"):
        self._db = sqlite3.connect(path, check_same_thread=False)
        self._lock = threading.Lock()
        self._db.execute(
            "CREATE VIRTUAL TABLE IF NOT EXISTS models USING fts5("
            "model_id UNINDEXED, category_name UNINDEXED, name, tags, category, description, "
            "tokenize = 'porter unicode61 remove_diacritics 2')"
        )

    @classmethod
    def build(cls, models: Iterable[ModelInfo], path: str = ":memory:") -> SearchIndex:
        index = cls(path)
        index.add(models)
        return index

    def add(self, models: Iterable[ModelInfo]) -> None:
        rows = [(m.id, m.category, m.name, " ".join(m.tags),
                 " ".join(split_camel(c) for c in m.category_path), m.description) for m in models]
        with self._lock, self._db:
            self._db.executemany("INSERT INTO models VALUES (?, ?, ?, ?, ?, ?)", rows)

    def search(self, text: str, limit: int = 20) -> list[SearchHit]:
        """Models matching ``text``, best first (all words; if none match, any word)."""
        for any_word in (False, True):
            query = fts_query(text, any_word=any_word)
            if query is None:
                return []
            with self._lock:
                rows = self._db.execute(
                    "SELECT model_id, category_name, name, bm25(models, 0, 0, ?, ?, ?, ?) AS rank "
                    "FROM models WHERE models MATCH ? ORDER BY rank, model_id LIMIT ?",
                    (*WEIGHTS, query, int(limit)),
                ).fetchall()
            if rows:
                return [SearchHit(mid, cat, name, -rank) for mid, cat, name, rank in rows]
        return []

    def __len__(self) -> int:
        with self._lock:
            return self._db.execute("SELECT count(*) FROM models").fetchone()[0]
