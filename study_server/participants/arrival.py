"""Arrival at an entry link: whom the link names, and whether this browser starts a session, resumes its own or is
refused.

An entry link names a platform id — Prolific's ``PROLIFIC_PID``, MTurk's ``workerId``, a plain link's ``pid``, or
none (an anonymous link: a new id) — with the platform's metadata, and may carry a pilot's signature
(:mod:`.pilots`). Then, in order:

- a browser that holds a session of this study (its cookie) and comes back with that session's id, or with none,
  resumes it (logged ``resume``, via the entry link);
- a new id gets a new session (:func:`.assignment.arrive`); when the browser already held another, both sessions
  are flagged (one person, two ids), unless either is a pilot's;
- an id that has a session already, asked for from a browser without it, resumes only when the link carries what
  only that participant's platform session has (:func:`proves`); otherwise the session is flagged and the browser
  refused: never a takeover.

Refusals are :class:`EntryRefused` errors whose message a participant reads on the entry page; what an arrival
records (sessions, flags, logs) is committed before one is raised.
"""

from __future__ import annotations

import hmac
import re
import secrets
import unicodedata

from flask import current_app
from flask_babel import gettext as _

from ..base.errors import StudyError
from ..base.extensions import db
from ..base.models import Participant, flag, log, log_again
from ..studies.study_file import Study
from . import assignment, pilots

#: Ids as the platforms issue them: Prolific's are 24 hex digits, MTurk's upper-case letters and digits.
PROLIFIC_ID = re.compile(r"[0-9a-fA-F]{24}")
MTURK_ID = re.compile(r"[A-Z0-9]{10,64}")
#: The only hosts an MTurk HIT may be submitted to (``turkSubmitTo``).
MTURK_SUBMIT = ("https://www.mturk.com", "https://workersandbox.mturk.com")
#: What MTurk sends as ``assignmentId`` while a worker previews a HIT (they have not accepted it).
MTURK_PREVIEW = "ASSIGNMENT_ID_NOT_AVAILABLE"
#: A plain link's ``pid``: up to LINK_ID_MAX visible characters — no control or format character (bidi overrides,
#: zero-width spaces, byte-order marks), line or paragraph separator, surrogate, private-use or unassigned code
#: point, any of which would let one id read as another on the admin pages and in the export.
LINK_ID_MAX = 128
INVISIBLE = frozenset(("Cc", "Cf", "Cs", "Co", "Cn", "Zl", "Zp"))
#: Code points Unicode says to ignore in display that are not of those categories (Hangul fillers, the combining
#: grapheme joiner, Mongolian and standard variation selectors).
IGNORABLE = re.compile("[\u034f\u115f\u1160\u17b4\u17b5\u180b-\u180f\u3164\ufe00-\ufe0f\uffa0"
                       "\U000e0100-\U000e01ef]")


class LinkProblem(Exception):
    """What is wrong with an entry link's parameters, said to the participant (translated)."""


class EntryRefused(StudyError):
    """An entry link that cannot start or resume a session here; the message is the entry page's."""


class BadLink(EntryRefused):
    """A parameter of the entry link is missing or malformed (logged to the application log, not the database:
    anyone can send these)."""

    status = 422


class NoPlatformId(EntryRefused):
    """A platform's study opened without the platform's id."""

    status = 400


class TooManyArrivals(EntryRefused):
    """The client address brought the study's hourly quota of new participants already."""

    status = 429


class InProgressElsewhere(EntryRefused):
    """The id's session belongs to another browser, and the link does not prove it is the same person's."""

    status = 409


def link_id(value: str) -> bool:
    """Whether ``value`` may be a plain link's ``pid`` (see INVISIBLE and IGNORABLE), written in Unicode's composed
    form (NFC: an id that looks like another is that other)."""
    return (0 < len(value) <= LINK_ID_MAX and not any(unicodedata.category(c) in INVISIBLE for c in value)
            and not IGNORABLE.search(value) and unicodedata.normalize("NFC", value) == value)


def is_preview(study: Study, args) -> bool:
    """Whether the link is an MTurk worker's preview of the HIT (shown the preview page, no session)."""
    return study.platform == "mturk" and args.get("assignmentId") == MTURK_PREVIEW


def platform_identity(study: Study, args) -> tuple[str, dict]:
    """(platform id, platform metadata) from the entry link's parameters ("" for an anonymous link); raises
    :class:`LinkProblem` naming a missing or malformed parameter."""
    def value(name: str, valid, required: bool = True) -> str:
        v = args.get(name, "")
        if not v and not required:
            return ""
        if not valid(v):
            raise LinkProblem(_("%(name)s is missing", name=name) if not v
                             else _("%(name)s is not a valid %(platform)s id", name=name, platform=study.platform))
        return v

    if study.platform == "prolific":
        meta = {"PROLIFIC_PID": value("PROLIFIC_PID", PROLIFIC_ID.fullmatch),
                "STUDY_ID": value("STUDY_ID", PROLIFIC_ID.fullmatch, required=bool(study.platform_study_id)),
                "SESSION_ID": value("SESSION_ID", PROLIFIC_ID.fullmatch, required=False)}
        if study.platform_study_id and meta["STUDY_ID"] != study.platform_study_id:
            raise LinkProblem(_("STUDY_ID is not this study's Prolific id"))
        return meta["PROLIFIC_PID"], meta
    if study.platform == "mturk":
        meta = {k: value(k, MTURK_ID.fullmatch) for k in ("workerId", "assignmentId", "hitId")}
        submit = args.get("turkSubmitTo", "").rstrip("/")
        if submit not in MTURK_SUBMIT:
            raise LinkProblem(_("turkSubmitTo is not one of MTurk's submit hosts"))
        meta["turkSubmitTo"] = submit
        return meta["workerId"], meta
    pid = value("pid", link_id, required=False)
    return pid, ({"pid": pid} if pid else {})


def is_pilot(study: Study, platform_id: str, args, key: str) -> bool:
    """Whether the entry link is a pilot's (signed with the server's ``key``: :mod:`.pilots`); a ``pilot`` parameter
    that is not this id's signature is refused (:class:`LinkProblem`), never taken for a participant's."""
    given = args.get(pilots.PARAM)
    if given is None:
        return False
    if not platform_id or not pilots.is_pilot(key, study.id, platform_id, given):
        raise LinkProblem(_("%(name)s is not a test link of this study", name=pilots.PARAM))
    return True


def proves(p: Participant, meta: dict) -> bool:
    """Whether an entry link carries what only this participant's platform session has: Prolific's
    SESSION_ID or MTurk's assignmentId, as first seen. A bare id (or a plain link's pid) proves nothing."""
    key = {"prolific": "SESSION_ID", "mturk": "assignmentId"}.get(p.platform)
    mine = (p.platform_meta or {}).get(key) if key else None
    return bool(mine) and hmac.compare_digest(str(mine).encode(), (meta.get(key) or "").encode())


def enter(study: Study, args, mine: Participant | None, user_agent: str, address: str | None, language: str,
          key: str) -> Participant:
    """The session this browser holds from now on, for an entry link with parameters ``args`` (see the module
    docstring); ``mine``: the session the browser's cookie names in this study; ``address``: the client's address
    key; ``language``: the one this browser would get; ``key``: the server's signing key. Commits what it records;
    raises :class:`EntryRefused`."""
    try:
        platform_id, meta = platform_identity(study, args)
        pilot = is_pilot(study, platform_id, args, key)
    except LinkProblem as e:
        current_app.logger.info("entry refused for study %s: %s", study.id, e)
        raise BadLink(_("This link cannot start the study: %(problem)s. Please open the study from the link on your "
                        "crowdsourcing platform.", problem=str(e))) from None
    if study.platform != "link" and not platform_id:
        raise NoPlatformId(_("Please open this study from the link on your crowdsourcing platform."))
    if mine is not None and (not platform_id or mine.platform_id == platform_id):
        log_again("resume", mine, via="entry link")
        db.session.commit()
        return mine
    if not platform_id:  # an anonymous link: a new id, remembered by this browser
        platform_id = "link-" + secrets.token_hex(8)
    try:
        p, created = assignment.arrive(study, study.platform, platform_id, meta, user_agent, address,
                                       language=language, pilot=pilot)
    except assignment.QuotaExceeded:
        current_app.logger.warning("arrival quota reached for an address in study %s", study.id)
        raise TooManyArrivals(_("Too many people have started this study from your network in the last hour. "
                                "Please try again later.")) from None
    if created and mine is not None and not (pilot or mine.pilot):  # one browser, a second id: flag both
        flag(p, f"this browser already took part as participant {mine.id} ({mine.status}, id "
                f"{mine.platform_id[:40]!r})")
        flag(mine, f"this browser came back as participant {p.id} under another id")
    elif not created:  # the id has a session already (begun in another browser, or a moment ago in another tab)
        if not proves(p, meta):  # someone else's id, or the participant in a new browser: never a takeover
            flag(p, "the study was opened with this participant's id in another browser without the platform's "
                    "session id (refused)", by=address)
            db.session.commit()
            raise InProgressElsewhere(_("This study is already in progress in another browser. Please continue "
                                        "there; if you cannot, contact the researcher through your platform."))
        log("resume", p, via="platform session")
    db.session.commit()
    return p
