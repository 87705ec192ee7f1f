"""What the experimenter decides and watches while a study runs: its progress per schedule row and condition, the
engines that answered, excluding a participant, clearing a flag. Each function changes the current transaction
and leaves committing to the caller; a decision is logged in the participant's session log."""

from __future__ import annotations

from collections import Counter

from sqlalchemy import func, select

from ..base.errors import StudyError
from ..base.extensions import db
from ..base.models import Participant, SessionLog, Trial, log, utcnow
from ..participants.assignment import fresh_after
from ..studies.study_file import Study

#: The longest reason for an exclusion kept (characters).
MAX_REASON = 1000


class ReasonMissing(StudyError):
    status = 400

    def __init__(self):
        super().__init__("A reason is required to exclude a participant.", "reason")


def state(status: str, row: int, seen, fresh) -> str:
    """Where a participant stands for the experimenter: ``visiting`` (arrived, not consented: no row, no data),
    ``in_progress`` (consented, seen since ``fresh``), ``stale`` (consented, not seen since), else the status."""
    if status != "in_progress":
        return status
    if row < 0:
        return "visiting"
    return "in_progress" if seen is not None and seen >= fresh else "stale"  # None: unreadable (column_types)


def progress(study: Study) -> dict:
    """Counts per schedule row and per condition of completed / in progress / stale / excluded / other (visitors
    who have not consented, and pilots, apart: ``totals["visiting"]``, ``totals["pilot"]``), the device check's
    reasons for those it screened out (``screened``: code → participants, study_server.participants.device), and the
    engines' use (:func:`engine_use`)."""
    fresh = fresh_after(study, utcnow())
    people = db.session.execute(select(Participant.row, Participant.status, Participant.last_seen_at,
                                       Participant.pilot).where(Participant.study_id == study.id)).all()
    rows = [Counter() for _ in range(study.n_rows)]
    totals = Counter()
    screened = Counter()
    for (report,) in db.session.execute(select(Participant.viewport).where(
            Participant.study_id == study.id, Participant.status == "screened_out", Participant.pilot.is_(False))):
        screened.update((report or {}).get("reasons", ()))
    for row, status, seen, pilot in people:
        if pilot:  # a test run or a simulated participant: not study data
            totals["pilot"] += 1
            continue
        where = state(status, row, seen, fresh)
        if 0 <= row < len(rows):
            rows[row][where] += 1
        totals[where] += 1
    trials = db.session.execute(
        select(Trial.condition, Trial.done_at.is_not(None), Participant.status, func.count())
        .join(Participant).where(Participant.study_id == study.id, Participant.pilot.is_(False),
                                 Trial.kind == "trial")
        .group_by(Trial.condition, Trial.done_at.is_not(None), Participant.status)).all()
    conditions = {c.id: Counter() for c in study.conditions}
    for condition, done, status, n in trials:  # not done: open while the session goes on, else never finished
        kind = "done" if done else "open" if status == "in_progress" else "unfinished"
        conditions.setdefault(condition, Counter())[kind] += n
    return {"rows": rows, "totals": totals, "conditions": conditions, "screened": screened,
            "engines": engine_use(study)}


def engine_use(study: Study) -> list[dict]:
    """Per condition that suggests: its engine, and how often another engine stood in for it (and why, the
    commonest reasons first)."""
    reasons: dict[str, Counter] = {}
    condition, reason = SessionLog.detail["condition"].as_string(), SessionLog.detail["reason"].as_string()
    for c, r, n in db.session.execute(select(condition, reason, func.count()).where(
            SessionLog.study_id == study.id, SessionLog.kind == "engine_fallback").group_by(condition, reason)):
        reasons.setdefault(str(c), Counter())[str(r)[:120]] += n
    circuits = {c.id: db.session.scalar(select(SessionLog).where(  # the last opening or closing of each circuit
        SessionLog.study_id == study.id, SessionLog.kind == "engine_circuit", condition == c.id)
        .order_by(SessionLog.id.desc()).limit(1)) for c in study.conditions if c.engine.name == "http"}
    return [{"condition": c.id, "engine": c.engine.name, "version": c.engine.kind.version,
             "fallback": c.engine.config.fallback.name if c.engine.name == "http" else None,
             "fallbacks": sum(reasons.get(c.id, Counter()).values()),
             "reasons": reasons.get(c.id, Counter()).most_common(3),
             "circuit": _circuit(circuits.get(c.id))} for c in study.conditions if c.mode]


def _circuit(row: SessionLog | None) -> str | None:
    """What the last logged change of an http engine's circuit says, for the dashboard (None: never opened)."""
    if row is None:
        return None
    detail = row.detail if isinstance(row.detail, dict) else {}
    at = f"{row.at:%Y-%m-%d %H:%M:%S} UTC" if row.at is not None else "(time unreadable)"
    if detail.get("state") == "open":
        return (f"opened {at} after {detail.get('failures')} failures "
                f"({str(detail.get('reason'))[:120]}): asked again every {detail.get('retry_s')} s or more")
    return f"closed {at}: the engine answers again"


def exclude(p: Participant, reason: str) -> None:
    """Exclude ``p`` from the analysis, saying why (:class:`ReasonMissing` without a reason; the first
    :data:`MAX_REASON` characters are kept)."""
    reason = reason.strip()[:MAX_REASON]
    if not reason:
        raise ReasonMissing()
    p.status = "excluded"
    p.excluded_reason = reason
    log("excluded", p, reason=reason)


def clear_flag(p: Participant, number: int) -> bool:
    """The experimenter has looked at flag ``number`` of ``p`` and clears it: it stays on record (cleared, when)
    and no longer makes the approval decision "review". False when it was cleared before."""
    flags = [dict(f) for f in p.flags]
    if flags[number].get("cleared_at"):
        return False
    flags[number]["cleared_at"] = utcnow().isoformat()
    p.flags = flags
    log("flag_cleared", p, reason=flags[number].get("reason"))
    return True
