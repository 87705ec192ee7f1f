"""How each participant's session ended, for the platform: the codes issued per way out (the admin's dashboard)
and the approval list an experimenter takes to Prolific or MTurk (``approvals.csv``).

A decision per participant: ``approve`` (completed, nothing flagged), ``review`` (completed but flagged, or
excluded: look before approving or rejecting), ``return`` (declined consent, screened out or left: the
platform should see the submission returned), ``pending`` (still in progress), ``pilot`` (a test run or a
simulated participant: nothing to decide on the platform).
"""

from __future__ import annotations

from sqlalchemy import func, select

from ..base.extensions import db
from ..base.models import Participant, open_flags
from .flow import is_open

#: The columns of approvals.csv. ``assignment``: MTurk's assignment id (what MTurk approves), once the session has
#: ended — an id that resumes a session is never written while it could (Prolific approves by participant id: its
#: SESSION_ID is never written at all).
APPROVAL_COLUMNS = ("participant", "platform", "platform_id", "assignment", "status", "code", "decision", "flags",
                    "finished_at")
RETURNED = ("no_consent", "screened_out", "returned")


def decision(p: Participant) -> str:
    if p.pilot:  # a test run or a simulated participant: not on the platform
        return "pilot"
    if p.status == "completed":
        return "review" if open_flags(p) else "approve"
    if p.status == "excluded":
        return "review"
    if p.status in RETURNED:
        return "return"
    return "pending"


def issued_codes(study_id: str) -> list[dict]:
    """Per way out (status) and code: how many participants got it (pilots' codes are not the platform's)."""
    rows = db.session.execute(select(Participant.status, Participant.code, func.count()).where(
        Participant.study_id == study_id, Participant.code.is_not(None), Participant.pilot.is_(False))
        .group_by(Participant.status,
                                                                                   Participant.code)
        .order_by(Participant.status))
    return [{"status": s, "code": c, "participants": n} for s, c, n in rows]


def approval_rows(study_id: str) -> list[dict]:
    """One row per participant who arrived, in arrival order."""
    people = db.session.scalars(select(Participant).where(Participant.study_id == study_id).order_by(Participant.id))
    return [{"participant": p.id, "platform": p.platform, "platform_id": p.platform_id,
             "assignment": (p.platform_meta or {}).get("assignmentId", "") if p.platform == "mturk" and
             not is_open(p) else "", "status": p.status,
             "code": p.code or "", "decision": decision(p), "flags": len(open_flags(p)),
             "finished_at": p.finished_at.isoformat() if p.finished_at else ""} for p in people]
