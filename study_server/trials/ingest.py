"""Event ingestion: batches stored all or nothing, idempotent by (participant, seq), never overwritten.

Concurrency assumptions: a batch is one transaction of ``INSERT … ON CONFLICT DO NOTHING`` rows (one statement),
so a batch sent twice (a retry after a lost answer, a second tab, a reload replaying its outbox under a new
page id) stores each event once, whichever copy wins; batches of one participant may arrive in any order and in
parallel. A seq that is already stored with *different* content (type, trial, client time or payload) is a
conflict: nothing of the batch is stored, the conflict is logged, and the answer names the batch positions and
the next free seq, under which the client sends those events again. The answer to a stored batch is the highest
seq up to which every event is stored (``acked_seq``): the client may forget events up to it.
"""

from __future__ import annotations

import re

from sqlalchemy import bindparam, func, select

from scenesuggest.contract.events import MAX_SEQ, EventError, check_version, validate_batch

from ..base.errors import StudyError
from ..base.extensions import db, json_text
from ..base.models import Event, Participant, log, log_again, utcnow
from ..base.security import Preview
from ..studies.study_file import Study
from .bulk_insert import COUNT, COUNT_WITH_QUOTA, insert_events

PAGE_ID_MAX = 64
PAGE_ID = re.compile(rf"[A-Za-z0-9_.-]{{1,{PAGE_ID_MAX}}}")


class Conflict(StudyError):
    """Seqs of the batch are stored with different content; ``positions`` index the batch."""

    def __init__(self, positions: list[int], seqs: list[int], next_seq: int):
        super().__init__(f"seq {', '.join(map(str, seqs[:5]))} already stored with different content: send these "
                         f"events again from seq {next_seq}", f"events[{positions[0]}].seq",
                         extra={"conflicts": positions, "next_seq": next_seq})
        self.positions, self.seqs, self.next_seq = positions, seqs, next_seq


class OverQuota(StudyError):
    """The participant's event or byte quota is used up."""

    status = 429

    def __init__(self):
        super().__init__("this session has stored as many events as a study allows", "events",
                         {"Retry-After": "300"})


def _same(stored: Event, e: dict) -> bool:
    return (stored.type == e["type"] and stored.trial == e["trial"] and stored.client_t == e["t"]
            and stored.payload == e["payload"])


def _conflicts(participant_id: int, batch: list[dict]) -> list[int]:
    """Positions of batch events whose seq is stored with other content, and that are not stored under another
    seq either (a copy renumbered by another tab counts as stored)."""
    rest = {e["seq"]: i for i, e in enumerate(batch)}
    stored = db.session.scalars(select(Event).where(Event.participant_id == participant_id,
                                                    Event.seq.in_(list(rest))))
    differing = sorted(rest[s.seq] for s in stored if not _same(s, batch[rest[s.seq]]))
    if not differing:
        return []
    times = {batch[i]["t"] for i in differing}
    elsewhere = list(db.session.scalars(select(Event).where(Event.participant_id == participant_id,
                                                            Event.client_t.in_(list(times)))))
    return [i for i in differing if not any(_same(s, batch[i]) for s in elsewhere)]


_EVENTS = Event.__table__.c
#: How many events of a participant are stored from a seq on, and the highest seq.
_STORED_FROM = select(func.count(), func.max(_EVENTS.seq)).where(_EVENTS.participant_id == bindparam("pid"),
                                                                 _EVENTS.seq >= bindparam("start"))


def contiguous_seq(participant_id: int, start: int) -> int:
    """The highest seq s ≥ start−1 such that every event from ``start`` to s is stored."""
    count, top = db.session.connection().execute(_STORED_FROM, {"pid": participant_id, "start": start}).one()
    if not count:
        return start - 1
    if top - start + 1 == count:  # no gap: the usual case, answered without reading every seq
        return top
    seqs = db.session.scalars(select(Event.seq).where(Event.participant_id == participant_id, Event.seq >= start)
                              .order_by(Event.seq))
    last = start - 1
    for s in seqs:
        if s != last + 1:
            break
        last = s
    return last


def _next_seqs(before: int, batch: list[dict], inserted: int) -> bool:
    """The usual batch: all of it new, its seqs the next ones after ``before`` (the participant's acked seq as
    read). Every seq up to its last is then stored (those up to ``before`` were; this transaction stores the
    rest), which answers without counting — exactly so when no event beyond it is stored, which the count of
    the participant's events tells once the batch is counted (:func:`store`)."""
    n = len(batch)
    if not n or inserted != n:
        return False
    seqs = [e["seq"] for e in batch]  # distinct (validated): n of them from before+1 to before+n are all of them
    return min(seqs) == before + 1 and max(seqs) == before + n


def store(participant: Participant, page_id: str, events: list, quota: tuple[int, int] | None = None,
          nbytes: int | None = None, vocabulary=None) -> int:
    """Validate (raising :class:`scenesuggest.contract.events.EventError`) and store a batch of a session that is still
    open (the caller checks :func:`study_server.participants.flow.is_open`); returns acked_seq. Raises :class:`Conflict`
    (nothing stored, the conflict logged) and
    :class:`OverQuota` when ``quota`` = (events, bytes) per participant would be exceeded. ``nbytes`` is the
    batch's size as sent (counted against the byte quota in proportion to the events it adds); ``vocabulary``
    the version of the event vocabulary the page speaks (absent: 1). Commits."""
    if not isinstance(page_id, str) or not PAGE_ID.fullmatch(page_id):
        raise EventError(f"expected 1 to {PAGE_ID_MAX} letters, digits, '.', '_' or '-'", "page_id")
    version = check_version(vocabulary)
    batch = validate_batch(events, version)
    now, pid, before = utcnow(), participant.id, participant.acked_seq
    if batch:
        common = {"participant_id": pid, "page_id": page_id, "server_t": now, "vocabulary": version}
        inserted = insert_events(common, batch)
        if inserted < len(batch):  # some seqs were stored before: the same events (a resend), or others
            positions = _conflicts(pid, batch)
            if positions:
                _refuse_conflict(participant, page_id, batch, positions)
        if nbytes is None:
            nbytes = sum(len(json_text(e["payload"]).encode()) for e in batch)
        size = nbytes * inserted // len(batch)
    else:
        inserted, size = 0, 0
    usual = _next_seqs(before, batch, inserted)
    acked = before + len(batch) if usual else contiguous_seq(pid, before + 1)
    # one statement: acked_seq only ever moves forwards (a slower parallel batch may commit after a faster one);
    # the quota is checked on the row as it is now, so parallel batches cannot each slip under it
    limited = quota is not None and inserted > 0
    values = {"pid": pid, "acked": acked, "n": inserted, "size": size, "now": now}
    if limited:
        values |= {"max_events": quota[0], "max_bytes": quota[1]}
    connection = db.session.connection()
    counted = connection.execute(COUNT_WITH_QUOTA if limited else COUNT, values).first()
    if counted is None:
        db.session.rollback()
        raise OverQuota()
    acked, stored = counted
    if usual and stored != acked + 1:  # events beyond it: a batch of later seqs was stored first, then count
        recount = {"pid": pid, "acked": contiguous_seq(pid, acked + 1), "n": 0, "size": 0, "now": now}
        acked = connection.execute(COUNT, recount).first()[0]
    db.session.commit()
    return acked  # the row's: a parallel batch may have moved it further


def take(who: Participant | Preview, study: Study, data: dict, nbytes: int | None) -> dict:
    """A batch posted to the API (``data``: ``page_id``, ``events``, ``vocabulary``; ``nbytes``: the request's
    size), answered as ``{"acked_seq", "stored"}``. An admin's preview's batch is validated and stored nowhere; a
    participant's is stored (:func:`store`) under the study's quotas of events and bytes per participant, and a
    batch over them is refused (:class:`OverQuota`) with the refusal logged, on one row however often it comes."""
    if isinstance(who, Preview):
        batch = validate_batch(data.get("events"), check_version(data.get("vocabulary")))
        return {"acked_seq": max((e["seq"] for e in batch), default=-1), "stored": False}
    quota = (study.max_events_per_participant, int(study.max_mb_per_participant * 1024 * 1024))
    try:
        acked = store(who, data.get("page_id"), data.get("events"), quota, nbytes, data.get("vocabulary"))
    except OverQuota:
        log_again("quota", who, what="events")
        db.session.commit()
        raise
    return {"acked_seq": acked, "stored": True}


def _refuse_conflict(participant: Participant, page_id: str, batch: list[dict], positions: list[int]):
    db.session.rollback()
    stored = db.session.scalar(select(func.max(Event.seq)).where(Event.participant_id == participant.id))
    next_seq = max(-1 if stored is None else stored, *(e["seq"] for e in batch)) + 1
    if next_seq + len(positions) > MAX_SEQ:  # someone stored the largest seqs: fill from the first gap instead
        next_seq = contiguous_seq(participant.id, participant.acked_seq + 1) + 1
    seqs = [batch[i]["seq"] for i in positions]
    log("event_conflict", participant, page_id=page_id, seqs=seqs[:50], next_seq=next_seq)
    db.session.commit()
    raise Conflict(positions, seqs, next_seq)
