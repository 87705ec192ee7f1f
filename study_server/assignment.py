"""Arrival and assignment: a platform id gets its one session, new ones the least-filled schedule row.

Concurrency assumptions (true with several threads, several gunicorn workers and several app servers on one
PostgreSQL): :func:`arrive` is one short transaction whose *first* statement increments the study's row in
``studies``. That write takes SQLite's database write lock (WAL, ``busy_timeout``) or PostgreSQL's row lock
before anything is read, so concurrent arrivals run one after the other, each counting the rows as the
previous one committed them. The unique constraint on (study, platform, platform id) backs this up.
"""

from __future__ import annotations

import secrets
from datetime import datetime, timedelta

from sqlalchemy import func, or_, select, update
from sqlalchemy.exc import IntegrityError

from .extensions import db
from .models import Participant, StudyRecord, Trial, log, utcnow
from .study_file import Study

#: Statuses that hold a row: finished participants and those still working (with a fresh heartbeat).
HOLDING = ("completed", "in_progress")


def insert_ignore(model, values: dict) -> None:
    """INSERT … ON CONFLICT DO NOTHING on SQLite and PostgreSQL."""
    dialect = db.session.get_bind().dialect.name
    if dialect == "postgresql":
        from sqlalchemy.dialects.postgresql import insert
    else:
        from sqlalchemy.dialects.sqlite import insert
    db.session.execute(insert(model).values(**values).on_conflict_do_nothing())


def ensure_study_record(study: Study) -> None:
    insert_ignore(StudyRecord, {"id": study.id, "title": study.title, "hash": study.hash, "assignments": 0,
                                "registered_at": utcnow()})
    db.session.commit()


def row_counts(study: Study, now: datetime) -> list[int]:
    """Participants holding each row: completed, plus in progress with a heartbeat newer than stale-after."""
    fresh = now - timedelta(minutes=study.stale_after_minutes)
    rows = db.session.execute(
        select(Participant.row, func.count()).where(
            Participant.study_id == study.id,
            or_(Participant.status == "completed",
                (Participant.status == "in_progress") & (Participant.last_seen_at >= fresh)),
        ).group_by(Participant.row)
    ).all()
    counts = [0] * study.n_rows
    for row, n in rows:
        if 0 <= row < len(counts):
            counts[row] = n
    return counts


def find(study: Study, platform: str, platform_id: str) -> Participant | None:
    return db.session.scalar(select(Participant).where(
        Participant.study_id == study.id, Participant.platform == platform, Participant.platform_id == platform_id))


def arrive(study: Study, platform: str, platform_id: str, meta: dict | None = None, user_agent: str = "",
           now: datetime | None = None) -> tuple[Participant, bool]:
    """The participant of ``platform_id`` (created=False), or a new one in the least-filled row (created=True)."""
    now = now or utcnow()
    existing = find(study, platform, platform_id)
    if existing is not None:
        return existing, False
    ensure_study_record(study)
    db.session.execute(update(StudyRecord).where(StudyRecord.id == study.id)
                       .values(assignments=StudyRecord.assignments + 1))  # the lock: first statement
    existing = find(study, platform, platform_id)
    if existing is not None:  # it arrived in another tab while we waited for the lock
        db.session.rollback()
        return find(study, platform, platform_id), False
    counts = row_counts(study, now)
    row = min(range(len(counts)), key=lambda r: (counts[r], r))
    seed = secrets.randbelow(2**31)
    p = Participant(study_id=study.id, study_hash=study.hash, platform=platform, platform_id=platform_id,
                    platform_meta=meta or {}, token=secrets.token_urlsafe(32), row=row, seed=seed,
                    status="in_progress", step="device", user_agent=user_agent[:512], created_at=now,
                    last_seen_at=now)
    db.session.add(p)
    db.session.flush()
    for position, t in enumerate(study.plan(row, seed)):
        db.session.add(Trial(participant_id=p.id, position=position, index=t.index, kind=t.kind,
                             condition=t.condition, scene_id=t.scene, period=t.period, block=t.block))
    log("arrive", p, row=row, counts=counts, platform=platform)
    try:
        db.session.commit()
    except IntegrityError:  # the unique constraint caught a duplicate that slipped past: use the winner's
        db.session.rollback()
        winner = find(study, platform, platform_id)
        if winner is None:
            raise
        return winner, False
    return p, True
