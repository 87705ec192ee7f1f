"""A corpus: scenes plus what is known of their models and categories."""

from __future__ import annotations

from collections.abc import Callable, Iterable
from dataclasses import dataclass, field

from ..library.index import ModelInfo
from ..scenes.scene import Scene
from ..scenes.taxonomy import Taxonomy

#: Wraps an iterable to show progress (e.g. a ``click.progressbar``); the identity by default.
Progress = Callable[[Iterable, str], Iterable]


def no_progress(items: Iterable, label: str = "") -> Iterable:
    return items


@dataclass
class Corpus:
    """Scenes in the world frame, the models they use and the taxonomy of their categories."""

    source: str
    scenes: list[Scene]
    models: dict[str, ModelInfo] = field(default_factory=dict)
    taxonomy: Taxonomy = field(default_factory=Taxonomy)
