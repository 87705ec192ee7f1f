"""Event ingestion: batches stored all or nothing, idempotent by (participant, seq), never overwritten.

Concurrency assumptions: a batch is one transaction of ``INSERT … ON CONFLICT DO NOTHING … RETURNING seq`` rows,
so a batch sent twice (a retry after a lost answer, a second tab, a reload replaying its outbox under a new
page id) stores each event once, whichever copy wins; batches of one participant may arrive in any order and in
parallel. A seq that is already stored with *different* content (type, trial, client time or payload) is a
conflict: nothing of the batch is stored, the conflict is logged, and the answer names the batch positions and
the next free seq, under which the client sends those events again. The answer to a stored batch is the highest
seq up to which every event is stored (``acked_seq``): the client may forget events up to it.
"""

from __future__ import annotations

import json
import re

from sqlalchemy import case, func, select, update

from scenesuggest.events import MAX_SEQ, EventError, check_version, validate_batch

from .extensions import db, insert_ignore
from .models import Event, Participant, log, utcnow

PAGE_ID_MAX = 64
PAGE_ID = re.compile(rf"[A-Za-z0-9_.-]{{1,{PAGE_ID_MAX}}}")


class Conflict(Exception):
    """Seqs of the batch are stored with different content; ``positions`` index the batch."""

    def __init__(self, positions: list[int], seqs: list[int], next_seq: int):
        super().__init__(f"seq {', '.join(map(str, seqs[:5]))} already stored with different content")
        self.positions, self.seqs, self.next_seq = positions, seqs, next_seq


class OverQuota(Exception):
    """The participant's event or byte quota is used up."""


def insert_events(rows: list[dict]) -> set[int]:
    """Insert the rows that are new; returns the seqs inserted."""
    statement = insert_ignore(Event, ["participant_id", "seq"]).returning(Event.seq)
    return set(db.session.scalars(statement, rows))


def _same(stored: Event, e: dict) -> bool:
    return (stored.type == e["type"] and stored.trial == e["trial"] and stored.client_t == e["t"]
            and stored.payload == e["payload"])


def _conflicts(participant_id: int, batch: list[dict], inserted: set[int]) -> list[int]:
    """Positions of batch events whose seq was already stored with other content, and that are not stored
    under another seq either (a copy renumbered by another tab counts as stored)."""
    rest = {e["seq"]: i for i, e in enumerate(batch) if e["seq"] not in inserted}
    if not rest:
        return []
    stored = db.session.scalars(select(Event).where(Event.participant_id == participant_id,
                                                    Event.seq.in_(list(rest))))
    differing = sorted(rest[s.seq] for s in stored if not _same(s, batch[rest[s.seq]]))
    if not differing:
        return []
    times = {batch[i]["t"] for i in differing}
    elsewhere = list(db.session.scalars(select(Event).where(Event.participant_id == participant_id,
                                                            Event.client_t.in_(list(times)))))
    return [i for i in differing if not any(_same(s, batch[i]) for s in elsewhere)]


def contiguous_seq(participant_id: int, start: int) -> int:
    """The highest seq s ≥ start−1 such that every event from ``start`` to s is stored."""
    seqs = db.session.scalars(select(Event.seq).where(Event.participant_id == participant_id, Event.seq >= start)
                              .order_by(Event.seq))
    last = start - 1
    for s in seqs:
        if s != last + 1:
            break
        last = s
    return last


def store(participant: Participant, page_id: str, events: list, quota: tuple[int, int] | None = None,
          nbytes: int | None = None, vocabulary=None) -> int:
    """Validate (raising :class:`scenesuggest.events.EventError`) and store a batch of a session that is still
    open (the caller checks :func:`study_server.flow.is_open`); returns acked_seq. Raises :class:`Conflict`
    (nothing stored, the conflict logged) and
    :class:`OverQuota` when ``quota`` = (events, bytes) per participant would be exceeded. ``nbytes`` is the
    batch's size as sent (counted against the byte quota in proportion to the events it adds); ``vocabulary``
    the version of the event vocabulary the page speaks (absent: 1). Commits."""
    if not isinstance(page_id, str) or not PAGE_ID.fullmatch(page_id):
        raise EventError(f"expected 1 to {PAGE_ID_MAX} letters, digits, '.', '_' or '-'", "page_id")
    version = check_version(vocabulary)
    batch = validate_batch(events, version)
    now = utcnow()
    if batch:
        rows = [{"participant_id": participant.id, "seq": e["seq"], "page_id": page_id, "type": e["type"],
                 "trial": e["trial"], "client_t": e["t"], "server_t": now, "payload": e["payload"],
                 "vocabulary": version} for e in batch]
        inserted = insert_events(rows)
        if len(inserted) < len(batch):
            positions = _conflicts(participant.id, batch, inserted)
            if positions:
                _refuse_conflict(participant, page_id, batch, positions)
        if nbytes is None:
            nbytes = sum(len(json.dumps(e["payload"])) for e in batch)
        size = nbytes * len(inserted) // len(batch)
    else:
        inserted, size = set(), 0
    acked = contiguous_seq(participant.id, participant.acked_seq + 1)
    # one statement: acked_seq only ever moves forwards (a slower parallel batch may commit after a faster one);
    # the quota is checked on the row as it is now, so parallel batches cannot each slip under it
    where = [Participant.id == participant.id]
    if quota is not None and inserted:
        where += [Participant.events_stored + len(inserted) <= quota[0], Participant.bytes_stored + size <= quota[1]]
    counted = db.session.execute(update(Participant).where(*where).values(
        acked_seq=case((Participant.acked_seq < acked, acked), else_=Participant.acked_seq),
        events_stored=Participant.events_stored + len(inserted), bytes_stored=Participant.bytes_stored + size,
        last_seen_at=now))
    if counted.rowcount != 1:
        db.session.rollback()
        raise OverQuota()
    db.session.commit()
    return participant.acked_seq  # reloaded after the commit


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
