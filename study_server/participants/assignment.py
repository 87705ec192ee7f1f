"""Arrival and assignment: a platform id gets its one session; a participant who consents gets the least-filled
schedule row. Arrivals that have not consented hold no row (``row = −1``) and have no trials yet.

Concurrency assumptions (true with several threads, several gunicorn workers and several app servers on one
PostgreSQL): :func:`assign` is one short transaction whose *first* statement increments the study's row in
``studies`` (writing it first if it is missing: :func:`_lock_study`). That write takes SQLite's database write
lock (WAL, ``busy_timeout``) or PostgreSQL's row lock before anything is read, so concurrent assignments run one
after the other, each counting the rows as the previous one committed them. :func:`arrive` only inserts; the
unique constraint on (study, platform, platform id) makes a second arrival of one id (another tab, another server)
find the first one's session.
"""

from __future__ import annotations

import secrets
from datetime import datetime, timedelta

from sqlalchemy import func, or_, select, update
from sqlalchemy.exc import IntegrityError

from ..base.errors import StudyError
from ..base.extensions import db, dialect_insert, insert_ignore
from ..base.models import Participant, StudyRecord, Trial, log, utcnow
from ..studies.study_file import Study


def _study_row(study: Study) -> dict:
    return {"id": study.id, "title": study.title, "hash": study.hash, "assignments": 0, "registered_at": utcnow()}


def _record_study(study: Study) -> None:
    """The study's row in ``studies`` (what participants refer to), written in the current transaction if missing."""
    db.session.execute(insert_ignore(StudyRecord), _study_row(study))


def _lock_study(study: Study) -> None:
    """Count one more assignment on the study's row, writing the row if it is missing: one statement, which takes
    the row's lock (the module's concurrency assumptions)."""
    upsert = dialect_insert(StudyRecord).on_conflict_do_update(index_elements=["id"],
                                                               set_={"assignments": StudyRecord.assignments + 1})
    db.session.execute(upsert, _study_row(study) | {"assignments": 1})


def fresh_after(study: Study, now: datetime) -> datetime:
    """A participant in progress whose last request is older than this is stale: their row is free again."""
    return now - timedelta(minutes=study.stale_after_minutes)


def row_counts(study: Study, now: datetime, pilot: bool = False) -> list[int]:
    """Participants holding each row: completed, plus in progress with a heartbeat newer than stale-after. Real
    participants and pilots are balanced apart (``pilot``): pilots never weigh on the study's balance, and a pilot
    run still goes through every row."""
    fresh = fresh_after(study, now)
    rows = db.session.execute(
        select(Participant.row, func.count()).where(
            Participant.study_id == study.id, Participant.pilot.is_(pilot),
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


class Removed(StudyError):
    """The participant's session was removed (``study reset``) while they consented."""

    status = 410

    def __init__(self):
        super().__init__("this session was removed", "participant")


class QuotaExceeded(StudyError):
    """Too many new participants from one client address within the hour."""

    status = 429

    def __init__(self):
        super().__init__("too many people have started this study from this network in the last hour")


def arrivals_from(study: Study, address: str, now: datetime) -> int:
    return db.session.scalar(select(func.count()).select_from(Participant).where(
        Participant.study_id == study.id, Participant.address == address, Participant.pilot.is_(False),
        Participant.created_at >= now - timedelta(hours=1))) or 0


def arrive(study: Study, platform: str, platform_id: str, meta: dict | None = None, user_agent: str = "",
           address: str | None = None, now: datetime | None = None, language: str | None = None,
           pilot: bool = False) -> tuple[Participant, bool]:
    """The participant of ``platform_id`` (created=False), or a new one without a row (created=True; a ``pilot``
    when the entry link was signed as one: study_server.participants.pilots). Raises :class:`QuotaExceeded` when
    ``address`` already brought the study's hourly quota of new arrivals (pilots, whom only the operator can send, are
    not counted against it)."""
    now = now or utcnow()
    existing = find(study, platform, platform_id)
    if existing is not None:
        return existing, False
    if not pilot and address is not None and arrivals_from(study, address, now) >= study.arrivals_per_address_per_hour:
        raise QuotaExceeded()
    _record_study(study)
    p = Participant(study_id=study.id, study_hash=study.hash, platform=platform, platform_id=platform_id,
                    platform_meta=meta or {}, token=secrets.token_urlsafe(32), row=-1,
                    seed=secrets.randbelow(2**31), status="in_progress", step="device", user_agent=user_agent[:512],
                    created_at=now, last_seen_at=now, flags=[], address=address,
                    language=language or study.languages[0], pilot=pilot)
    db.session.add(p)
    try:
        db.session.flush()
        log("arrive", p, platform=platform)
        db.session.commit()
    except IntegrityError:  # the same id arrived in another tab or on another server first: use that session
        db.session.rollback()
        winner = find(study, platform, platform_id)
        if winner is None:
            raise
        return winner, False
    return p, True


def assign(study: Study, p: Participant, now: datetime | None = None) -> int:
    """Give a consenting participant the least-filled schedule row and its trials (once); returns the row.
    Ends the caller's transaction first and commits its own (see the module's concurrency assumptions)."""
    now = now or utcnow()
    participant_id = p.id
    db.session.commit()
    _lock_study(study)  # the lock: first statement
    found = db.session.execute(select(Participant.row, Participant.pilot).where(Participant.id == participant_id)
                               ).first()
    if found is None:  # removed meanwhile (a reset): nothing to assign
        db.session.rollback()
        raise Removed()
    row, pilot = found
    if row is not None and row >= 0:  # assigned already (a second tab consented first)
        db.session.rollback()
        db.session.refresh(p)
        return row
    counts = row_counts(study, now, pilot)
    row = min(range(len(counts)), key=lambda r: (counts[r], r))
    db.session.execute(update(Participant).where(Participant.id == participant_id).values(row=row))
    for position, t in enumerate(study.plan(row, p.seed)):
        db.session.add(Trial(participant_id=participant_id, position=position, index=t.index, kind=t.kind,
                             condition=t.condition, scene_id=t.scene, period=t.period, block=t.block))
    log("assign", p, row=row, counts=counts)
    db.session.commit()
    db.session.refresh(p)
    return row
