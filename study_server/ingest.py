"""Event ingestion: batches stored all or nothing, idempotent by (participant, seq).

Concurrency assumptions: a batch is one transaction of ``INSERT … ON CONFLICT DO NOTHING`` rows, so a batch
sent twice (a retry after a lost answer, a second tab, a reload replaying its outbox) stores each event
once, whichever copy wins; batches of one participant may arrive in any order and in parallel. The answer
is the highest seq up to which every event is stored (``acked_seq``): the client may forget events up to it.
"""

from __future__ import annotations

from sqlalchemy import select, update

from scenesuggest.events import EventError, validate_batch

from .extensions import db
from .models import Event, Participant, utcnow

PAGE_ID_MAX = 64


def insert_events(rows: list[dict]) -> None:
    dialect = db.session.get_bind().dialect.name
    if dialect == "postgresql":
        from sqlalchemy.dialects.postgresql import insert
    else:
        from sqlalchemy.dialects.sqlite import insert
    db.session.execute(insert(Event).on_conflict_do_nothing(index_elements=["participant_id", "seq"]), rows)


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


def store(participant: Participant, page_id: str, events: list) -> int:
    """Validate (raising :class:`scenesuggest.events.EventError`) and store a batch; returns acked_seq.
    Commits."""
    if not isinstance(page_id, str) or not page_id or len(page_id) > PAGE_ID_MAX:
        raise EventError(f"expected a string of 1 to {PAGE_ID_MAX} characters", "page_id")
    batch = validate_batch(events)
    now = utcnow()
    if batch:
        insert_events([{"participant_id": participant.id, "seq": e["seq"], "page_id": page_id, "type": e["type"],
                        "trial": e["trial"], "client_t": e["t"], "server_t": now, "payload": e["payload"]}
                       for e in batch])
    acked = contiguous_seq(participant.id, participant.acked_seq + 1)
    # only ever move acked_seq forwards, even when a slower parallel batch commits after a faster one
    db.session.execute(update(Participant).where(Participant.id == participant.id, Participant.acked_seq < acked)
                       .values(acked_seq=acked))
    db.session.execute(update(Participant).where(Participant.id == participant.id).values(last_seen_at=now))
    db.session.commit()
    return participant.acked_seq  # reloaded after the commit
