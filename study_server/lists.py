"""The lists the server shows a participant — context suggestions and search results — built and recorded.

Every list is stored (``lists``: its query and its items with ranks) before it is answered, so the export can
say what a participant saw at which rank; an admin's preview builds the same lists and stores nothing.
"""

from __future__ import annotations

import json
import uuid
from collections.abc import Callable
from datetime import timedelta

from sqlalchemy import func, select, update

from scenesuggest import frames
from scenesuggest.suggest import ContextQuery, SuggestionList

from .extensions import db
from .models import Participant, ShownList, utcnow
from .studies import StudyRuntime

#: Suggestions a context list shows (the engine ranks every category; these many are placed and oriented).
SUGGESTIONS_SHOWN = 40
#: Models offered per suggested category.
MODELS_PER_CATEGORY = 12
#: Lists a participant may have the server store within any ``LIST_WINDOW`` (context suggestions and searches
#: together): 2.5 a second, sustained — above anyone's pace in the editor (a search is typed, a suggestion asked
#: for with a click), far below a script's. Beyond it: 429 with Retry-After, which the page waits out.
LIST_RATE = 300
LIST_WINDOW = timedelta(minutes=2)


class TooManyLists(Exception):
    """Over the list rate or the participant's storage quota; ``retry_after`` in seconds."""

    def __init__(self, message: str, retry_after: int):
        super().__init__(message)
        self.retry_after = retry_after


def check_rate(who: Participant) -> None:
    """Refuse (:class:`TooManyLists`) a participant who has had ``LIST_RATE`` lists stored within the last
    ``LIST_WINDOW``: one look at the ``LIST_RATE``-th newest of their lists (by the index on participant and time)."""
    now = utcnow()
    nth = db.session.scalar(select(ShownList.created_at).where(ShownList.participant_id == who.id)
                            .order_by(ShownList.created_at.desc()).offset(LIST_RATE - 1).limit(1))
    if nth is not None and nth > now - LIST_WINDOW:
        raise TooManyLists(f"more than {LIST_RATE} lists in {int(LIST_WINDOW.total_seconds())} s: wait a moment",
                           max(1, int((nth + LIST_WINDOW - now).total_seconds()) + 1))


def check_room(who: Participant, size: int, quota_bytes: int) -> None:
    """Refuse a list of ``size`` bytes that would take the participant beyond their storage quota (lists count
    against the same bytes as events: a participant's stored data is bounded whatever they send)."""
    if (who.bytes_stored or 0) + size > quota_bytes:
        raise TooManyLists("this session has stored as much as a study allows", 300)


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


def record(who: Participant | None, trial: int | None, source: str, query: dict, items: list[dict],
           quota_bytes: int) -> str:
    """Store a shown list (nothing for a preview, ``who`` None); returns its id. The list counts against the
    participant's storage quota (:class:`TooManyLists`; the rate is checked before the list is made,
    :func:`check_rate`). The caller commits."""
    list_id = uuid.uuid4().hex
    if who is not None:
        size = len(json.dumps(query)) + len(json.dumps(items))
        # one UPDATE that adds and checks at once: an event batch stored meanwhile is counted, never overwritten
        counted = db.session.execute(update(Participant).where(
            Participant.id == who.id, func.coalesce(Participant.bytes_stored, 0) + size <= quota_bytes)
            .values(bytes_stored=func.coalesce(Participant.bytes_stored, 0) + size)
            .execution_options(synchronize_session=False))
        if counted.rowcount != 1:
            raise TooManyLists("this session has stored as much as a study allows", 300)
        db.session.add(ShownList(id=list_id, participant_id=who.id, trial=trial, source=source, query=query,
                                 items=items, created_at=utcnow()))
    return list_id
