"""The schema (typed SQLAlchemy 2 models). It only ever changes through a migration in ``migrations/``.

Times are naive UTC datetimes (``utcnow``); client times are milliseconds since the epoch as sent.
"""

from __future__ import annotations

from datetime import UTC, datetime

from sqlalchemy import (
    BigInteger,
    Float,
    ForeignKey,
    Index,
    Integer,
    SmallInteger,
    String,
    Text,
    UniqueConstraint,
)
from sqlalchemy.orm import Mapped, mapped_column

from .column_types import Document, Time
from .extensions import db

#: Event ids outgrow 32 bits in long studies; SQLite needs INTEGER for its row-id alias.
BigId = BigInteger().with_variant(Integer(), "sqlite")


def utcnow() -> datetime:
    return datetime.now(UTC).replace(tzinfo=None)


class StudyRecord(db.Model):
    """A study known to this database; its row is also the lock that serialises assignment."""

    __tablename__ = "studies"
    id: Mapped[str] = mapped_column(String(64), primary_key=True)
    title: Mapped[str] = mapped_column(String(200))
    hash: Mapped[str] = mapped_column(String(64))
    assignments: Mapped[int] = mapped_column(Integer, default=0)
    registered_at: Mapped[datetime] = mapped_column(Time, default=utcnow)


class Participant(db.Model):
    __tablename__ = "participants"
    __table_args__ = (UniqueConstraint("study_id", "platform", "platform_id", name="uq_participant_platform_id"),)
    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    study_id: Mapped[str] = mapped_column(ForeignKey("studies.id"), index=True)
    study_hash: Mapped[str] = mapped_column(String(64))
    platform: Mapped[str] = mapped_column(String(16))
    platform_id: Mapped[str] = mapped_column(String(128))
    platform_meta: Mapped[dict] = mapped_column(Document, default=dict)
    token: Mapped[str] = mapped_column(String(64), unique=True, index=True)
    row: Mapped[int] = mapped_column(Integer, index=True)  # −1 until consent (no schedule row held)
    seed: Mapped[int] = mapped_column(Integer)
    status: Mapped[str] = mapped_column(String(16), default="in_progress", index=True)
    step: Mapped[str] = mapped_column(String(24), default="device")
    instruction_page: Mapped[int] = mapped_column(Integer, default=0)
    position: Mapped[int] = mapped_column(Integer, default=0)  # current trial, as a position in the plan
    acked_seq: Mapped[int] = mapped_column(Integer, default=-1)  # highest contiguous event seq stored
    consent_version: Mapped[str | None] = mapped_column(String(64), nullable=True)
    code: Mapped[str | None] = mapped_column(String(64), nullable=True)
    excluded_reason: Mapped[str | None] = mapped_column(Text, nullable=True)
    user_agent: Mapped[str] = mapped_column(String(512), default="")
    #: The language the participant's pages speak, chosen at arrival (study_server.base.i18n.choose); None before.
    language: Mapped[str | None] = mapped_column(String(16), nullable=True)
    viewport: Mapped[dict | None] = mapped_column(Document, nullable=True)
    created_at: Mapped[datetime] = mapped_column(Time, default=utcnow)
    last_seen_at: Mapped[datetime] = mapped_column(Time, default=utcnow, index=True)
    finished_at: Mapped[datetime | None] = mapped_column(Time, nullable=True)
    #: Why the experimenter should look at this participant: [{"reason": text, "at": ISO time, "by": the keyed
    #: address of the request that raised it, "times": how often it was raised, "cleared_at": when the
    #: experimenter cleared it (absent while open)}, …].
    flags: Mapped[list] = mapped_column(Document, default=list)
    #: Keyed hash of the client address at arrival (for per-address quotas; the address itself is not kept).
    address: Mapped[str | None] = mapped_column(String(32), nullable=True, index=True)
    events_stored: Mapped[int] = mapped_column(Integer, default=0)
    bytes_stored: Mapped[int] = mapped_column(BigInteger, default=0)
    #: A pilot: the experimenter's test run or a simulated participant, arrived through a signed entry link
    #: (study_server.participants.pilots); kept out of the rows' balance, the targets' freeze, the approvals and the
    #: analysis.
    pilot: Mapped[bool] = mapped_column(db.Boolean, default=False, server_default="0")


class Trial(db.Model):
    __tablename__ = "trials"
    __table_args__ = (UniqueConstraint("participant_id", "position", name="uq_trial_position"),)
    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    participant_id: Mapped[int] = mapped_column(ForeignKey("participants.id"), index=True)
    position: Mapped[int] = mapped_column(Integer)
    index: Mapped[int] = mapped_column(Integer)  # −1 practice, then 0, 1, …
    kind: Mapped[str] = mapped_column(String(16))
    condition: Mapped[str] = mapped_column(String(16))
    scene_id: Mapped[str] = mapped_column(String(64))
    period: Mapped[int] = mapped_column(Integer)
    block: Mapped[int] = mapped_column(Integer)
    started_at: Mapped[datetime | None] = mapped_column(Time, nullable=True)
    done_at: Mapped[datetime | None] = mapped_column(Time, nullable=True)
    #: When the page with the condition's instructions was first shown before this trial, and when the participant
    #: dismissed it (flow.briefing_due: the first trial, and every trial whose condition differs from the one
    #: before); None when none was due. The time between them is not trial time: the trial starts after.
    briefing_shown_at: Mapped[datetime | None] = mapped_column(Time, nullable=True)
    briefed_at: Mapped[datetime | None] = mapped_column(Time, nullable=True)
    final_scene: Mapped[dict | None] = mapped_column(Document, nullable=True)
    #: Why the trial should be reviewed: its events do not show the study's minimum work, or its scene came less
    #: close to the target than the study's min_target_score (None: neither, or not yet checked).
    review: Mapped[str | None] = mapped_column(Text, nullable=True)
    #: Whether the trial's events rebuild the final scene it submitted (scenesuggest.contract.replay): "match",
    #: "mismatch: …" (what differs), "pending: …" (waiting for events the page logged before "done"), or
    #: "unavailable: …" (events without object states, or the check failed); empty before "done".
    replay: Mapped[str | None] = mapped_column(Text, nullable=True)
    #: The last seq the page logged before "done" while the replay check waits for it to be stored (None: the
    #: check is not waiting); trial_check.settle makes the check when it arrives.
    replay_waits_for: Mapped[int | None] = mapped_column(Integer, nullable=True)
    #: How close the final scene came to the target (scenesuggest.contract.scoring), 0..1; empty before "done".
    score: Mapped[float | None] = mapped_column(Float, nullable=True)
    #: The whole closeness result found at "done" (scenesuggest.contract.scoring.Closeness.record: score, matched,
    #: missing, extra, errors in metres and degrees, the matched pairs), exported as stored; {"unavailable": why}
    #: when the check failed, None before "done" or for trials done before it was stored (the export computes those).
    closeness: Mapped[dict | None] = mapped_column(Document, nullable=True)

    def describe(self) -> dict:
        """The trial as every page and answer names it: index, kind, condition, scene and block (each adds what it
        needs besides)."""
        return {"index": self.index, "kind": self.kind, "condition": self.condition, "scene": self.scene_id,
                "block": self.block}


class Event(db.Model):
    __tablename__ = "events"
    __table_args__ = (UniqueConstraint("participant_id", "seq", name="uq_event_seq"),)
    id: Mapped[int] = mapped_column(BigId, primary_key=True)
    #: Looked up through uq_event_seq, whose leading column it is (no index of its own).
    participant_id: Mapped[int] = mapped_column(ForeignKey("participants.id"))
    seq: Mapped[int] = mapped_column(Integer)
    page_id: Mapped[str] = mapped_column(String(64))
    type: Mapped[str] = mapped_column(String(32))
    trial: Mapped[int | None] = mapped_column(Integer, nullable=True)
    client_t: Mapped[float] = mapped_column(Float)
    server_t: Mapped[datetime] = mapped_column(Time, default=utcnow)
    payload: Mapped[dict] = mapped_column(Document, default=dict)
    #: The version of the event vocabulary the page spoke (scenesuggest.contract.events.VERSIONS).
    vocabulary: Mapped[int] = mapped_column(SmallInteger, default=1, server_default="1")


class ShownList(db.Model):
    """Every list the server gave a participant (context suggestions, search results), with its ranks."""

    __tablename__ = "lists"
    #: A participant's lists by time: what the list rate's one look reads (lists.check_rate).
    __table_args__ = (Index("ix_lists_participant_created", "participant_id", "created_at"),)
    id: Mapped[str] = mapped_column(String(32), primary_key=True)
    participant_id: Mapped[int] = mapped_column(ForeignKey("participants.id"))
    trial: Mapped[int | None] = mapped_column(Integer, nullable=True)
    source: Mapped[str] = mapped_column(String(16))
    query: Mapped[dict] = mapped_column(Document)
    items: Mapped[list] = mapped_column(Document)
    created_at: Mapped[datetime] = mapped_column(Time, default=utcnow)


class SurveyResponse(db.Model):
    __tablename__ = "surveys"
    __table_args__ = (UniqueConstraint("participant_id", "survey", name="uq_survey"),)
    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    participant_id: Mapped[int] = mapped_column(ForeignKey("participants.id"), index=True)
    survey: Mapped[str] = mapped_column(String(32))
    answers: Mapped[dict] = mapped_column(Document)
    created_at: Mapped[datetime] = mapped_column(Time, default=utcnow)


class SessionLog(db.Model):
    """What the server saw of a participant's session: arrivals, resumes, steps, friendly failures."""

    __tablename__ = "session_log"
    id: Mapped[int] = mapped_column(BigId, primary_key=True)
    participant_id: Mapped[int | None] = mapped_column(ForeignKey("participants.id"), index=True, nullable=True)
    study_id: Mapped[str | None] = mapped_column(String(64), nullable=True)
    kind: Mapped[str] = mapped_column(String(32))
    detail: Mapped[dict] = mapped_column(Document, default=dict)
    at: Mapped[datetime] = mapped_column(Time, default=utcnow)


class LoginAttempt(db.Model):
    """An admin login attempt, counted per client (``ip`` holds the client key: a device or an address).
    ``ok`` is None while the password is being checked, so parallel guesses count before they are decided."""

    __tablename__ = "login_attempts"
    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    ip: Mapped[str] = mapped_column(String(64), index=True)
    ok: Mapped[bool | None] = mapped_column(db.Boolean, nullable=True)
    at: Mapped[datetime] = mapped_column(Time, default=utcnow, index=True)


class AdminSession(db.Model):
    """A signed-in admin browser; its id is in the session cookie. Logout deletes the row, so a copied cookie
    stops working; sessions also end after an idle and an absolute lifetime."""

    __tablename__ = "admin_sessions"
    id: Mapped[str] = mapped_column(String(64), primary_key=True)
    created_at: Mapped[datetime] = mapped_column(Time, default=utcnow)
    last_seen_at: Mapped[datetime] = mapped_column(Time, default=utcnow)


class AdminLink(db.Model):
    """A one-time admin sign-in link printed by ``scenesuggest study admin-link``: its id is the SHA-256 of the
    link's secret; it works once, before ``expires_at``, whatever failed logins have done meanwhile."""

    __tablename__ = "admin_links"
    id: Mapped[str] = mapped_column(String(64), primary_key=True)
    created_at: Mapped[datetime] = mapped_column(Time, default=utcnow)
    expires_at: Mapped[datetime] = mapped_column(Time)
    used_at: Mapped[datetime | None] = mapped_column(Time, nullable=True)


def log(kind: str, participant: Participant | None = None, study_id: str | None = None, **detail) -> None:
    """Add a session-log row to the current transaction."""
    db.session.add(SessionLog(participant_id=participant.id if participant else None,
                              study_id=study_id or (participant.study_id if participant else None), kind=kind,
                              detail=detail))


#: How far back :func:`log_again` looks for the same row (a reload and a re-opened link alternate).
LOG_AGAIN_WINDOW = 8


def log_again(kind: str, participant: Participant, **detail) -> None:
    """Log what a participant can repeat at will (a reload, a re-opened link, a request refused): when one of
    their last few session-log rows says the same, it counts one more (``times``, ``last_at``) instead of adding a
    row, so repeating it cannot grow the log."""
    from sqlalchemy import select

    recent = db.session.scalars(select(SessionLog).where(SessionLog.participant_id == participant.id)
                                .order_by(SessionLog.id.desc()).limit(LOG_AGAIN_WINDOW))
    for row in recent:
        if row.kind == kind and {k: v for k, v in (row.detail or {}).items()
                                 if k not in ("times", "last_at")} == detail:
            row.detail = {**row.detail, "times": min(int(row.detail.get("times", 1)) + 1, 10**9),
                          "last_at": utcnow().isoformat()}
            return
    log(kind, participant, **detail)


def flag(participant: Participant, reason: str, by: str | None = None) -> None:
    """Mark a participant for the experimenter's review (shown in the admin, exported), and log it. ``by``: the
    keyed address of the request that raised it (another browser's, for a refused attempt on this id). A reason
    is recorded once while open; raising it again counts (whoever repeats a refused request cannot grow the
    list)."""
    flags = [dict(f) for f in participant.flags or []]
    for f in flags:
        if f.get("reason") == reason and not f.get("cleared_at"):
            f["times"] = min(int(f.get("times", 1)) + 1, 10**6)
            f["last_at"] = utcnow().isoformat()
            participant.flags = flags
            return
    participant.flags = [*flags, {"reason": reason, "at": utcnow().isoformat(), "times": 1,
                                  **({"by": by} if by else {})}]
    log("flagged", participant, reason=reason, by=by)


def open_flags(participant: Participant) -> list[dict]:
    """The flags the experimenter has not cleared: what makes a completed participant's decision "review"."""
    return [f for f in participant.flags or [] if not f.get("cleared_at")]


__all__ = ["AdminLink", "AdminSession", "Event", "LoginAttempt", "Participant", "SessionLog", "ShownList",
           "StudyRecord", "SurveyResponse", "Trial", "flag", "log", "log_again", "open_flags", "utcnow"]
