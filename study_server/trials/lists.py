"""The lists the server shows a participant — context suggestions and search results — built and recorded, each
by one call (:func:`suggest`, :func:`search`).

Every list is stored (``lists``: its query and its items with ranks) before it is answered, so the export can
say what a participant saw at which rank; an admin's preview builds the same lists and stores nothing.
"""

from __future__ import annotations

import uuid
from contextlib import contextmanager
from datetime import timedelta

from flask import current_app
from sqlalchemy import func, insert, select, update

from scenesuggest.errors import SceneSuggestError
from scenesuggest.suggestion.suggest import ContextQuery, Suggestion, SuggestionList

from ..base import i18n
from ..base.errors import StudyError
from ..base.extensions import db, json_text
from ..base.models import Participant, ShownList, log, log_again, utcnow
from ..participants.flow import current_trial
from ..studies.served import EngineNotLoaded, StudyRuntime
from .posted_scenes import live_scene

#: Suggestions a context list shows (the engine ranks every category; these many are placed and oriented).
SUGGESTIONS_SHOWN = 40
#: Models offered per suggested category.
MODELS_PER_CATEGORY = 12
#: Lists a participant may have the server store within any ``LIST_WINDOW`` (context suggestions and searches
#: together): 2.5 a second, sustained — above anyone's pace in the editor (a search is typed, a suggestion asked
#: for with a click), far below a script's. Beyond it: 429 with Retry-After, which the page waits out.
LIST_RATE = 300
LIST_WINDOW = timedelta(minutes=2)


class NoSuggestions(StudyError):
    """A click for suggestions in a trial whose interface has none (``none``)."""

    status = 403

    def __init__(self):
        super().__init__("this trial's interface has no suggestions", "trial")


class QueryRejected(StudyError):
    """A click the engine cannot answer (an unknown parent object, a point that is not three numbers, …)."""

    status = 400


class SuggestionsUnavailable(StudyError):
    """The condition's engine cannot be loaded just now (why is in the server's log, not told to the participant)."""

    status = 503

    def __init__(self):
        super().__init__("suggestions are unavailable just now: try again, or place objects from the list", "engine")


class TooManyLists(StudyError):
    """Over the list rate or the participant's storage quota; ``retry_after`` in seconds."""

    status = 429

    def __init__(self, message: str, retry_after: int, field: str | None = None):
        super().__init__(message, field, {"Retry-After": str(retry_after)})
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


def shown_item(s: Suggestion, rank: int, label: str, models: list[dict]) -> dict:
    """A suggestion as the API shows it: the engine's (:meth:`~scenesuggest.suggestion.suggest.Suggestion.to_dict`)
    without its terms, ranked among the suggestions shown, with the category's ``label`` and its ``models``
    described (:meth:`StudyRuntime.describe`)."""
    d = s.to_dict()
    del d["terms"]
    return {**d, "rank": rank, "label": label, "models": models}


def stored_item(item: dict) -> dict:
    """A shown suggestion (:func:`shown_item`) as a stored list keeps it: rank, category, score and model ids."""
    return {"rank": item["rank"], "category": item["category"], "score": item["score"],
            "models": [m["id"] for m in item["models"]]}


def context_list(rt: StudyRuntime, condition: str, scene, parent, point, normal) -> tuple[list[dict], SuggestionList]:
    """(items, the engine's answer) for a click on ``parent`` at ``point`` (metres, world frame) with ``normal``:
    ranked categories that this study's library can place, each with its placement (4×4, column-major, world
    frame), attachment face, heading and models (as :meth:`StudyRuntime.describe` gives them); the answer says
    which engine answered and, when the condition's engine could not, why (``fallback``). Raises
    :class:`scenesuggest.errors.SceneSuggestError` for a query the engine cannot answer."""
    engine = rt.engine(condition)
    query = ContextQuery(scene, parent, point, normal)
    found = engine.suggest(query, rt.study.condition(condition).mode, top=SUGGESTIONS_SHOWN,
                           only=rt.placeable(condition))
    items, language = [], i18n.page_language()
    for s in found:
        models = [rt.library[m] for m in s.models if m in rt.library] or rt.by_category.get(s.category, [])
        if not models:
            continue  # a category without a model in this study's library cannot be placed
        items.append(shown_item(s, len(items) + 1, i18n.category_label(s.category, language),
                                [rt.describe(m, language) for m in models[:MODELS_PER_CATEGORY]]))
        if len(items) >= SUGGESTIONS_SHOWN:
            break
    return items, found


def _store(who: Participant, trial: int | None, source: str, query: dict, items: list[dict],
           quota_bytes: int) -> str:
    """Store a shown list for ``who`` (seen now); returns its id. The list counts against the participant's storage
    quota (:class:`TooManyLists`; the rate is checked before the list is made, :func:`check_rate`)."""
    list_id, now = uuid.uuid4().hex, utcnow()
    size = len(json_text(query).encode()) + len(json_text(items).encode())  # as stored
    # one UPDATE that adds and checks at once (an event batch stored meanwhile is counted, never overwritten) and
    # says the participant was seen now
    counted = db.session.execute(update(Participant).where(
        Participant.id == who.id, func.coalesce(Participant.bytes_stored, 0) + size <= quota_bytes)
        .values(bytes_stored=func.coalesce(Participant.bytes_stored, 0) + size, last_seen_at=now)
        .execution_options(synchronize_session=False))
    if counted.rowcount != 1:
        raise TooManyLists("this session has stored as much as a study allows", 300, source)
    db.session.execute(insert(ShownList), {"id": list_id, "participant_id": who.id, "trial": trial, "source": source,
                                           "query": query, "items": items, "created_at": now})
    return list_id


@contextmanager
def _refusals_logged(who: Participant | None, source: str):
    """A participant over the list rate or storage quota: the refusal counted on one session-log row (committed:
    it outlives the refused request) and raised on (429 with Retry-After)."""
    try:
        yield
    except TooManyLists as e:
        if who is None:
            raise
        db.session.rollback()
        log_again("quota", who, what=f"{source} lists", reason=str(e))
        db.session.commit()
        e.field = source
        raise


def _quota_bytes(rt: StudyRuntime) -> int:
    return int(rt.study.max_mb_per_participant * 1024 * 1024)


def suggest(rt: StudyRuntime, who: Participant | None, condition: str, scene_id: str, trial: int,
            data: dict) -> dict:
    """A participant's click asking for suggestions (``data``: the editor's live ``scene``, the clicked ``parent``
    object, ``point`` and ``normal``, metres, world frame), answered as the API gives it: the list built, stored
    under an id (nothing stored for an admin's preview, ``who`` None), a stand-in engine logged. Refuses a
    participant over the list rate or quota before the engine runs (:class:`TooManyLists`), a query the engine
    cannot answer (:class:`QueryRejected`) and an engine that cannot be loaded (:class:`SuggestionsUnavailable`).
    The caller commits."""
    interface = rt.study.condition(condition)
    if interface.mode is None:
        raise NoSuggestions()
    with _refusals_logged(who, "context"):
        if who is not None:
            check_rate(who)
            check_room(who, 0, _quota_bytes(rt))
        scene = live_scene(data.get("scene"), rt.scene_type(scene_id))
        try:
            items, found = context_list(rt, condition, scene, data.get("parent"), data.get("point"),
                                        data.get("normal"))
        except SceneSuggestError as e:
            raise QueryRejected(e.message, e.field) from None
        except EngineNotLoaded as e:
            current_app.logger.error("%s", e)
            raise SuggestionsUnavailable() from None
        query = {"parent": data.get("parent"), "point": data.get("point"), "normal": data.get("normal"),
                 "surface_type": found.surface_type, "engine": found.engine,
                 **({"fallback": found.fallback} if found.fallback else {})}
        list_id = (_store(who, trial, "context", query, [stored_item(i) for i in items], _quota_bytes(rt))
                   if who else uuid.uuid4().hex)
    if who is not None and found.fallback:
        log("engine_fallback", who, condition=condition, trial=trial, engine=interface.engine.name,
            answered_by=found.engine, reason=found.fallback, list_id=list_id)
    return {"list_id": list_id, "condition": condition, "mode": interface.mode,
            "surface_type": found.surface_type, "engine": found.engine, "suggestions": items}


def search(rt: StudyRuntime, who: Participant | None, text: str, limit: int) -> dict:
    """A participant's text search (at most ``limit`` hits, best first), answered as the API gives it and stored
    like a suggestion list under the current trial (nothing for a preview, ``who`` None). Refuses a participant
    over the list rate or quota before searching (:class:`TooManyLists`). The caller commits."""
    current = current_trial(who) if who is not None else None
    trial = current.index if current is not None else None
    with _refusals_logged(who, "search"):
        if who is not None:
            check_rate(who)
            check_room(who, 0, _quota_bytes(rt))
        hits = rt.search_index.search(text, limit)
        shown = [{"rank": i + 1, "model": h.model_id, "category": h.category} for i, h in enumerate(hits)]
        list_id = _store(who, trial, "search", {"text": text}, shown, _quota_bytes(rt)) if who else uuid.uuid4().hex
    language = i18n.page_language()
    return {"list_id": list_id, "query": text,
            "hits": [dict(rt.describe(rt.library[h.model_id], language), rank=i + 1) for i, h in enumerate(hits)]}
