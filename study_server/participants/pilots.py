"""Pilot participants: the experimenter's test runs and simulated participants, kept apart from a study's data.

A pilot arrives through an entry link that carries ``pilot=`` a signature of the study and the participant's
platform id made with the server's secret key (:func:`entry_query`): only someone who holds the key — the
operator, ``study serve`` printing a test link, ``study simulate`` — can make one, so no participant can mark
themselves (or anyone else) a pilot. A pilot is an ordinary session in every other way; it is marked
(``participants.pilot``) and so

- takes a schedule row without counting in the rows' balance, and does not freeze the study's targets;
- is counted apart on the dashboard, decided ``pilot`` in the approval list, and sent nowhere at the end (no
  platform redirect, no MTurk submission);
- is a column of the export, and left out of the report when the data hold anyone else;
- is removed by ``study reset`` (:func:`reset`), which refuses to remove real participants unless forced.

Entry links are shaped for the study's platform, as the platform would send them: Prolific's three 24-hex ids
(``STUDY_ID`` the study's own when its file names it), MTurk's worker, assignment and HIT ids with the sandbox as
``turkSubmitTo``, or a link study's ``pid``.
"""

from __future__ import annotations

import hashlib
import hmac
import secrets
from urllib.parse import urlencode

from sqlalchemy import delete, func, select, update

from ..base.config import instance_path
from ..base.errors import StudyError
from ..base.extensions import db
from ..base.models import Event, Participant, SessionLog, ShownList, StudyRecord, SurveyResponse, Trial
from ..studies.study_file import Study

#: The pilot database's file in the instance folder: where ``study simulate`` puts simulated participants unless
#: told otherwise, apart from every study's own data.
PILOT_DATABASE = "pilot.sqlite3"

#: The entry link's parameter that carries the signature.
PARAM = "pilot"
#: Hex digits of the signature (128 bits).
DIGITS = 32


def database_url() -> str:
    """The pilot database (SQLite, in the instance folder: ``SCENESUGGEST_INSTANCE``)."""
    return f"sqlite:///{instance_path() / PILOT_DATABASE}"


def signature(secret_key: str | bytes, study_id: str, platform_id: str) -> str:
    """The pilot signature of ``platform_id`` in study ``study_id`` under the server's ``secret_key``."""
    key = secret_key.encode() if isinstance(secret_key, str) else secret_key
    message = f"scenesuggest-pilot\0{study_id}\0{platform_id}".encode()
    return hmac.new(key, message, hashlib.sha256).hexdigest()[:DIGITS]


def is_pilot(secret_key: str | bytes, study_id: str, platform_id: str, given: str) -> bool:
    """Whether ``given`` is the pilot signature of ``platform_id`` (compared in constant time)."""
    return hmac.compare_digest(signature(secret_key, study_id, platform_id).encode(), given.encode())


def entry_query(secret_key: str | bytes, study: Study) -> dict[str, str]:
    """A fresh pilot's entry-link parameters, shaped for ``study``'s platform and signed."""
    if study.platform == "prolific":
        query = {"PROLIFIC_PID": secrets.token_hex(12), "STUDY_ID": study.platform_study_id or secrets.token_hex(12),
                 "SESSION_ID": secrets.token_hex(12)}
        platform_id = query["PROLIFIC_PID"]
    elif study.platform == "mturk":
        query = {"workerId": "PILOT" + secrets.token_hex(6).upper(), "assignmentId": secrets.token_hex(15).upper(),
                 "hitId": secrets.token_hex(15).upper(), "turkSubmitTo": "https://workersandbox.mturk.com"}
        platform_id = query["workerId"]
    else:
        platform_id = "pilot-" + secrets.token_hex(8)
        query = {"pid": platform_id}
    return query | {PARAM: signature(secret_key, study.id, platform_id)}


#: What a platform appends to the study's entry URL (Prolific's placeholders, which it fills in per participant).
PLATFORM_QUERY = {"prolific": "PROLIFIC_PID={{%PROLIFIC_PID%}}&STUDY_ID={{%STUDY_ID%}}&SESSION_ID={{%SESSION_ID%}}"}


def participant_link(study: Study, start_url: str) -> str:
    """The link participants are given, for ``study``'s platform: Prolific's study URL with its placeholders; MTurk's
    external question URL (MTurk adds its ids); a link study's URL (each visitor gets an id of their own; add
    ``pid=`` an unguessable id per person to know who is who)."""
    query = PLATFORM_QUERY.get(study.platform)
    return f"{start_url}?{query}" if query else start_url


def test_link(secret_key: str | bytes, study: Study, start_url: str) -> str:
    """A fresh pilot's link (:func:`entry_query`): whoever opens it takes the study as a pilot."""
    return f"{start_url}?{urlencode(entry_query(secret_key, study))}"


class RealParticipants(StudyError):
    """A reset that would remove participants who are not pilots."""

    status = 409


def counts(study_id: str) -> dict[str, int]:
    """Participants of the study who arrived: ``pilot`` and ``real`` (everyone else)."""
    found = dict(db.session.execute(select(Participant.pilot, func.count()).where(Participant.study_id == study_id)
                                    .group_by(Participant.pilot)).all())
    return {"pilot": int(found.get(True, 0)), "real": int(found.get(False, 0))}


def check_reset(study_id: str, found: dict[str, int], pilots_only: bool, force: bool) -> None:
    """Refuse (:class:`RealParticipants`) a reset that would remove real participants without ``force``."""
    if not pilots_only and found["real"] and not force:
        raise RealParticipants(f"{found['real']} real participant(s) have arrived in study {study_id!r}: a reset "
                               "would delete their data. Remove only the pilots (--pilots-only), or back up the "
                               "database first ('scenesuggest study backup') and reset with --force", "--force")


def reset(study_id: str, *, pilots_only: bool = False, force: bool = False) -> dict[str, int]:
    """Remove the study's participants with everything they left (trials, events, lists, surveys, session log);
    with ``pilots_only``, only the pilots. Removing real participants needs ``force`` (else
    :class:`RealParticipants`, naming how many; and without it only pilots are deleted, so a real participant who
    arrives between the count and the deletion stays). Changes the current transaction; returns the rows removed
    per table."""
    check_reset(study_id, counts(study_id), pilots_only, force)
    # without force only pilots go, whatever the count said: a participant arriving meanwhile stays
    chosen = [Participant.study_id == study_id] + ([] if force and not pilots_only else [Participant.pilot.is_(True)])
    ids = select(Participant.id).where(*chosen).scalar_subquery()
    removed = {name: db.session.execute(delete(table).where(table.participant_id.in_(ids))).rowcount
               for table, name in ((Event, "events"), (ShownList, "lists"), (SurveyResponse, "surveys"),
                                   (Trial, "trials"), (SessionLog, "session_log"))}
    if not pilots_only:  # the study's own log (engine fallbacks) and its count of assignments start afresh
        removed["session_log"] += db.session.execute(delete(SessionLog).where(
            SessionLog.study_id == study_id, SessionLog.participant_id.is_(None))).rowcount
        db.session.execute(update(StudyRecord).where(StudyRecord.id == study_id).values(assignments=0))
    removed["participants"] = db.session.execute(delete(Participant).where(*chosen)).rowcount
    return removed
