"""What an engine may suggest: a category someone could want and place.

A corpus has categories for its own bookkeeping — the room shell every scene hangs from (``Room``) and the label of
a model nobody named (``Unknown``). They are never suggested, whatever the corpus or the engine; a study narrows the
rest further to what its library can place (an engine's ``only``). This module is the one place that decides: each
local engine's ranking (``Engine.suggest`` and ``explain``), the evaluation's ranks and its held-out queries, and
the check of an HTTP engine's answers (``engines.wire.parse_answer``) ask it.
"""

from __future__ import annotations

from collections.abc import Iterable

import numpy as np

from ..scenes.scene import PLACEHOLDERS

__all__ = ["PLACEHOLDERS", "suggestable", "suggestable_mask"]


def suggestable(category: str) -> bool:
    """Whether ``category`` may ever be suggested (it is not a placeholder)."""
    return category not in PLACEHOLDERS


def suggestable_mask(categories: Iterable[str]) -> np.ndarray:
    """(n,) bool: which of ``categories`` may be suggested."""
    return np.array([suggestable(c) for c in categories], dtype=bool)
