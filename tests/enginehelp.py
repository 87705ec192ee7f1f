"""Asking engines in tests: an http engine on a URL, and a query where a target object of the demo's desk corner
stands."""

from __future__ import annotations

from pathlib import Path

from support import DEMO_FOLDER

from scenesuggest import engines
from scenesuggest.engines.http import HttpEngine
from scenesuggest.engines.protocol import LoadContext
from scenesuggest.scenes import scene_json
from scenesuggest.suggestion.query import ContextQuery


def http_engine(url: str, priors: Path, **options) -> HttpEngine:
    spec = engines.configure({"name": "http", "url": url, **options})
    return engines.load(spec, LoadContext(priors))


def a_query() -> ContextQuery:
    """A click where a target object of the demo's desk corner stands (the object removed)."""
    scene = scene_json.load(DEMO_FOLDER / "scenes" / "desk-corner.json")
    o = next(o for o in scene if o.parent is not None and o.contact_point is not None)
    return ContextQuery(scene.without(o.id), o.parent, o.contact_point, o.contact_normal)
