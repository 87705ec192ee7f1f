"""Engines by name: the registry of :class:`~.protocol.EngineKind` s and the one way to configure and load one.

Built in: ``paper`` (the paper's factors, :class:`scenesuggest.suggestion.suggest.Engine`, with its options),
``learned`` (a learning-to-rank engine over the paper's factors and the scene's context, :mod:`.learned`), ``frequency``
(categories by how often they occur: a control) and ``http`` (an engine in any language behind HTTP, with a
fallback, :mod:`.http`). Other packages add kinds through the entry-point group ``scenesuggest.engines``: an entry
``name = "package.module:KIND"`` whose object is an :class:`~.protocol.EngineKind` (or a class of one) with that
``name``. A study condition names its engine as a table, ``engine = { name = "learned", … }``; a table without
``name`` is the paper's engine with those options (:func:`configure`).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from functools import cache
from importlib import import_module
from importlib.metadata import entry_points
from pathlib import Path
from typing import Any

from ..errors import SceneSuggestError
from .protocol import EngineKind, LoadContext, SuggestionEngine

GROUP = "scenesuggest.engines"
DEFAULT = "paper"
#: The kinds this package ships, by name: module and attribute (imported on first use).
BUILT_IN = {"paper": ("scenesuggest.engines.paper", "KIND"), "learned": ("scenesuggest.engines.learned", "KIND"),
            "frequency": ("scenesuggest.engines.frequency", "KIND"), "http": ("scenesuggest.engines.http", "KIND")}

__all__ = ["BUILT_IN", "DEFAULT", "EngineKind", "EngineSpec", "LoadContext", "SuggestionEngine", "configure",
           "kind", "names"]


@dataclass(frozen=True)
class EngineSpec:
    """A condition's engine: its kind's name, its options as the study file gives them (``raw``, for the
    manifest) and as the kind configured them (``config``)."""

    name: str
    raw: Mapping[str, Any]
    config: Any

    @property
    def kind(self) -> EngineKind:
        return kind(self.name)


def _plugins() -> dict[str, Any]:
    """Entry points of the group, by name (a built-in name taken by another package is an error at use)."""
    return {ep.name: ep for ep in entry_points(group=GROUP)}


@cache
def kind(name: str) -> EngineKind:
    """The engine kind registered as ``name``; an unknown name is an error that lists the known ones."""
    if not isinstance(name, str) or name not in names():
        raise SceneSuggestError(f"unknown engine {name!r}: one of {', '.join(names())}", field="name")
    if name in BUILT_IN:
        module, attribute = BUILT_IN[name]
        other = _plugins().get(name)
        if other is not None and other.value.replace(" ", "") != f"{module}:{attribute}":
            raise SceneSuggestError(f"the engine name {name!r} is taken by another package ({other.value}): rename "
                                    "that package's engine", field="name")
        found = getattr(import_module(module), attribute)
    else:
        ep = _plugins()[name]
        try:
            found = ep.load()
        except Exception as e:  # noqa: BLE001 - a broken plugin is named, with what went wrong
            raise SceneSuggestError(f"the engine {name!r} ({ep.value}) cannot be loaded: {type(e).__name__}: {e}",
                                    field="name") from None
    found = found() if isinstance(found, type) else found
    if not isinstance(found, EngineKind) or found.name != name:
        raise SceneSuggestError(f"the engine {name!r} is not an EngineKind named {name!r}", field="name")
    return found


def names() -> tuple[str, ...]:
    """Every registered engine name: the built-in ones, then those of installed packages, sorted."""
    return (*BUILT_IN, *sorted(n for n in _plugins() if n not in BUILT_IN))


def configure(table: Mapping[str, Any] | None, base: Path | None = None) -> EngineSpec:
    """A condition's engine from its table: ``name`` (default ``paper``) and the kind's options. Errors are
    :class:`SceneSuggestError` s whose ``field`` is the key within the table (``name``, or the option)."""
    table = dict(table or {})
    name = table.pop("name", DEFAULT)
    if not isinstance(name, str):
        raise SceneSuggestError("expected the name of an engine", field="name")
    k = kind(name)
    return EngineSpec(name, {"name": name, **table}, k.configure(table, base))


def load(spec: EngineSpec, context: LoadContext) -> SuggestionEngine:
    """Load the engine of ``spec`` (its kind reads its file, or connects, as it needs)."""
    return spec.kind.load(spec.config, context)
