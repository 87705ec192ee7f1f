"""The lists the server shows a participant — context suggestions and search results — built and recorded.

Every list is stored (``lists``: its query and its items with ranks) before it is answered, so the export can
say what a participant saw at which rank; an admin's preview builds the same lists and stores nothing.
"""

from __future__ import annotations

import uuid
from collections.abc import Callable

from scenesuggest import frames
from scenesuggest.suggest import ContextQuery, SuggestionList

from .extensions import db
from .models import ShownList
from .studies import StudyRuntime

#: Suggestions a context list shows (the engine ranks every category; these many are placed and oriented).
SUGGESTIONS_SHOWN = 40
#: Models offered per suggested category.
MODELS_PER_CATEGORY = 12


def context_list(rt: StudyRuntime, condition: str, scene, parent, point, normal,
                 describe: Callable) -> tuple[list[dict], SuggestionList]:
    """(items, the engine's answer) for a click on ``parent`` at ``point`` (metres, world frame) with ``normal``:
    ranked categories that this study's library can place, each with its placement (4×4, column-major, world
    frame), attachment face, heading and models (as ``describe(model)`` gives them); the answer says which engine
    answered and, when the condition's engine could not, why (``fallback``). Raises
    :class:`scenesuggest.errors.SceneSuggestError` for a query the engine cannot answer."""
    engine = rt.engine(condition)
    query = ContextQuery(scene, parent, point, normal)
    found = engine.suggest(query, "full" if condition == "full" else "basic", top=SUGGESTIONS_SHOWN,
                           only=rt.placeable(condition))
    items = []
    for s in found:
        models = [rt.library[m] for m in s.models if m in rt.library] or rt.by_category.get(s.category, [])
        if not models:
            continue  # a category without a model in this study's library cannot be placed
        items.append({"rank": len(items) + 1, "category": s.category, "score": s.score,
                      "placement": frames.to_column_major(s.placement), "attachment_face": s.attachment_face,
                      "heading_deg": s.heading_deg, "notes": list(s.notes),
                      "models": [describe(m) for m in models[:MODELS_PER_CATEGORY]]})
        if len(items) >= SUGGESTIONS_SHOWN:
            break
    return items, found


def record(participant_id: int | None, trial: int | None, source: str, query: dict, items: list[dict]) -> str:
    """Store a shown list (nothing for a preview, ``participant_id`` None); returns its id. The caller commits."""
    list_id = uuid.uuid4().hex
    if participant_id is not None:
        db.session.add(ShownList(id=list_id, participant_id=participant_id, trial=trial, source=source, query=query,
                                 items=items))
    return list_id
