"""The participant's progress, owned by the server: which step they are on and what moves them on.

Steps: ``device`` → ``consent`` → ``demographics`` → ``instructions`` → ``trial`` (the practice trial first,
when the study has one; before the first trial and wherever the condition changes, a page with the condition's
instructions, which the participant dismisses before the trial starts) → ``exit`` → ``done``. Ending early:
declining consent (status ``no_consent``), failing the device check (``screened_out``), leaving (``returned``).
Each way out gives its own code (the study file's ``[platform.codes]``), which the platform's completion URL takes.
Every function takes the participant, changes it in the current transaction and leaves committing to the caller,
but :func:`takes_posts`, whose refusal is committed at once (it outlives the refused request).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from datetime import timedelta
from urllib.parse import quote

from flask_babel import gettext as _
from sqlalchemy import case, func, select, update

from ..base.errors import StudyError
from ..base.extensions import db
from ..base.models import Event, Participant, SessionLog, SurveyResponse, Trial, flag, log, log_again, utcnow
from ..studies.study_file import Question, Study
from . import device
from .assignment import assign

MAX_ANSWER = 5000


def trials(p: Participant) -> list[Trial]:
    return list(db.session.scalars(select(Trial).where(Trial.participant_id == p.id).order_by(Trial.position)))


def current_trial(p: Participant) -> Trial | None:
    if p.step != "trial":
        return None
    return db.session.scalar(select(Trial).where(Trial.participant_id == p.id, Trial.position == p.position))


#: The status of a session that still takes pages, events and trials; every other status is final.
OPEN = "in_progress"


class SessionEnded(StudyError):
    """The session ended (completed, excluded, …) before this step could end it."""

    status = 410

    def __init__(self):
        super().__init__("this session has ended", "status")


class BriefingDue(StudyError):
    """A trial finished whose condition's instructions the participant has not dismissed (its page never showed)."""

    def __init__(self, index: int):
        super().__init__(f"trial {index} has not begun: its condition's instructions come first", "trial")


class NotCurrentTrial(StudyError):
    """A trial finished that is neither the current one nor one finished before."""

    def __init__(self, index: int):
        super().__init__(f"trial {index} is not the current trial", "trial")


def is_open(p: Participant) -> bool:
    return p.status == OPEN


def _finish(p: Participant, study: Study, status: str, code_key: str) -> None:
    """End the session, only if it is still in progress as stored now: an exclusion (or an earlier end) that
    committed meanwhile is final (:class:`SessionEnded`)."""
    values = {"status": status, "step": "done", "code": study.codes.get(code_key), "finished_at": utcnow()}
    ended = db.session.execute(update(Participant).where(Participant.id == p.id, Participant.status == OPEN)
                               .values(**values))
    if ended.rowcount != 1:
        raise SessionEnded()
    for key, value in values.items():
        setattr(p, key, value)
    log("finish", p, status=status)


def check_device(p: Participant, study: Study, report: dict) -> bool:
    """Record the browser's report (:func:`study_server.participants.device.parse_report`) and the reasons, if any, that
    the study screens it out (:func:`study_server.participants.device.screen`): then the session ends before consent,
    holding no schedule row."""
    reasons = device.screen(report, study, p.user_agent)
    p.viewport = {**report, "reasons": reasons}
    log("device_check", p, ok=not reasons, **p.viewport)
    if reasons:
        _finish(p, study, "screened_out", "screened_out")
        return False
    p.step = "consent"
    return True


def give_consent(p: Participant, study: Study, agree: bool) -> None:
    if not agree:
        log("consent", p, agree=False, version=study.consent_version)
        _finish(p, study, "no_consent", "no_consent")
        return
    p.consent_version = study.consent_version
    log("consent", p, agree=True, version=study.consent_version)
    p.step = "demographics" if study.demographics else "instructions"


def answer_consent(p: Participant, study: Study, agree: bool) -> None:
    """The participant's answer at the consent step (nothing when they are past it): agreeing first takes a
    schedule row and the trials (:func:`.assignment.assign`, which commits), then moves on; declining ends the
    session. A second tab that moved on meanwhile, or an exclusion committed meanwhile, is left as it is."""
    if p.step != "consent":
        return
    if agree:
        assign(study, p)  # p is fresh after it
    if p.step == "consent" and is_open(p):
        try:
            give_consent(p, study, agree)
        except SessionEnded:
            db.session.rollback()


def validate_answers(questions: tuple[Question, ...], form) -> tuple[dict, dict[str, str]]:
    """(answers, errors by question id) for a submitted survey form."""
    answers, errors = {}, {}
    for q in questions:
        raw = form.get(q.id, "")
        raw = raw.strip() if isinstance(raw, str) else ""
        if not raw:
            if q.required:
                errors[q.id] = _("Please answer this question.")
            answers[q.id] = None
            continue
        if q.kind == "likert":
            if not raw.isdigit() or not 1 <= int(raw) <= q.scale:
                errors[q.id] = _("Please choose a value from 1 to %(scale)s.", scale=q.scale)
            else:
                answers[q.id] = int(raw)
        elif q.kind == "choice":
            if raw not in q.options:
                errors[q.id] = _("Please choose one of the options.")
            else:
                answers[q.id] = raw
        elif q.kind == "number":
            try:
                value = float(raw)
                if not math.isfinite(value):
                    raise ValueError
            except ValueError:
                errors[q.id] = _("Please enter a number.")
                continue
            if (q.minimum is not None and value < q.minimum) or (q.maximum is not None and value > q.maximum):
                errors[q.id] = _("Please enter a number between %(low)s and %(high)s.", low=f"{q.minimum:g}",
                                   high=f"{q.maximum:g}")
            else:
                answers[q.id] = int(value) if value.is_integer() else value
        else:
            answers[q.id] = raw[:MAX_ANSWER]
    return answers, errors


def save_survey(p: Participant, name: str, answers: dict) -> None:
    existing = db.session.scalar(select(SurveyResponse).where(SurveyResponse.participant_id == p.id,
                                                              SurveyResponse.survey == name))
    if existing is None:
        db.session.add(SurveyResponse(participant_id=p.id, survey=name, answers=answers))
    else:  # a resubmission (back button): keep the latest answers
        existing.answers = answers


def submit_demographics(p: Participant, study: Study, answers: dict) -> None:
    save_survey(p, "demographics", answers)
    p.step = "instructions"
    p.instruction_page = 0


def turn_instructions(p: Participant, study: Study, direction: str) -> None:
    if direction == "back":
        p.instruction_page = max(0, p.instruction_page - 1)
    elif p.instruction_page + 1 < len(study.instructions):
        p.instruction_page += 1
    else:
        p.step = "trial"
        p.position = 0
    log("instructions", p, page=p.instruction_page, step=p.step)


def briefing_due(p: Participant, t: Trial | None, plan: list[Trial] | None = None) -> bool:
    """Whether the condition's instructions are shown before the current trial ``t``: before the first trial and
    whenever the condition differs from the trial before it (the interface changes), until the participant has
    dismissed them. A trial already begun (begun before briefings were shown) has none. ``plan``: the
    participant's trials in order (:func:`trials`), when the caller has them (else the one before is read)."""
    if t is None or t.briefed_at is not None or t.started_at is not None:
        return False
    if t.position == 0:
        return True
    if plan is not None:
        return plan[t.position - 1].condition != t.condition
    before = db.session.scalar(select(Trial.condition).where(Trial.participant_id == p.id,
                                                             Trial.position == t.position - 1))
    return before != t.condition


def show_briefing(p: Participant, t: Trial) -> None:
    """The page of ``t``'s condition's instructions is shown: its first showing is when its time starts."""
    if t.briefing_shown_at is None:
        t.briefing_shown_at = utcnow()
        log("briefing_shown", p, position=t.position, index=t.index, condition=t.condition)


def finish_briefing(p: Participant, position: int | None) -> None:
    """The participant dismissed the condition's instructions shown before the trial at ``position`` (the page's
    own): only instructions that were shown and are still due are dismissed, so a repeated, stale or blind request
    changes nothing; the trial starts when its page is next shown."""
    t = current_trial(p)
    if t is None or t.position != position or t.briefing_shown_at is None or not briefing_due(p, t):
        return
    t.briefed_at = utcnow()
    log("briefing_read", p, position=t.position, index=t.index, condition=t.condition,
        seconds=round(briefing_seconds(t), 3))


@dataclass(frozen=True)
class TrialPage:
    """What the current trial's page shows: the trial, how many trials there are, and either the page of its
    condition's instructions (``briefing``) or the trial itself, with the seconds its briefing took (None: none)."""

    trial: Trial
    of: int
    briefing: bool
    briefing_seconds: float | None


def open_trial(p: Participant) -> TrialPage:
    """The current trial's page: the instructions of its condition when they are due (shown now), else the trial
    (started now)."""
    everything = trials(p)  # in order: a trial's position is its place here
    t = everything[p.position]
    of = sum(1 for x in everything if x.kind == "trial")
    if briefing_due(p, t, everything):
        show_briefing(p, t)
        return TrialPage(t, of, True, None)
    start_trial(p, t)
    return TrialPage(t, of, False, briefing_seconds(t))


def briefing_seconds(t: Trial) -> float | None:
    """Seconds the condition's instructions were open before ``t`` (server clock; None when none were shown)."""
    if t.briefed_at is None or t.briefing_shown_at is None:
        return None
    return (t.briefed_at - t.briefing_shown_at).total_seconds()


def start_trial(p: Participant, t: Trial) -> None:
    """The current trial ``t``'s page is shown: its first showing is when it starts."""
    if t.started_at is None:
        t.started_at = utcnow()
        log("trial_start", p, position=t.position, index=t.index)


def finish_trial(p: Participant, study: Study, index: int, scene: dict | None) -> Trial:
    """Mark the current trial done (idempotent for an already finished one) and move on."""
    t = current_trial(p)
    if t is None or t.index != index:
        done = db.session.scalar(select(Trial).where(Trial.participant_id == p.id, Trial.index == index))
        if done is not None and done.done_at is not None:
            return done  # a retried request: nothing to do
        raise NotCurrentTrial(index)
    if briefing_due(p, t):
        raise BriefingDue(index)
    now = utcnow()
    t.started_at = t.started_at or now
    t.done_at = now
    t.final_scene = scene
    timed_out = (now - t.started_at) > timedelta(minutes=study.trial_minutes)
    log("trial_done", p, position=t.position, index=t.index, timed_out=timed_out)
    p.position += 1
    if p.position >= len(trials(p)):
        p.step = "exit"
    return t


def check_session_time(p: Participant, study: Study) -> None:
    """Past the session time limit, a participant still in the trials goes on to the exit survey."""
    if p.step == "trial" and p.created_at is not None and \
            utcnow() - p.created_at > timedelta(minutes=study.session_minutes):  # None: unreadable (column_types)
        log("session_time_limit", p, position=p.position)
        p.step = "exit"


def visit(p: Participant, study: Study) -> None:
    """A view of the participant's current page: past the session time limit the trials end
    (:func:`check_session_time`); a view of the same place as the last one is a resume (a reload, the back button, a
    second tab), counted on one row; the participant was seen now."""
    check_session_time(p, study)
    where = {"step": p.step, "position": p.position, "page": p.instruction_page}
    last = db.session.scalar(select(SessionLog).where(SessionLog.participant_id == p.id,
                                                      SessionLog.kind.in_(("view", "resume")))
                             .order_by(SessionLog.id.desc()).limit(1))
    if last is not None and last.detail.get("where") == where:
        log_again("resume", p, where=where)
    else:
        log("view", p, where=where)
    p.last_seen_at = utcnow()


def takes_posts(p: Participant, path: str) -> bool:
    """Whether the participant's session still takes a form posted to ``path``: an ended one does not (the refusal
    is logged and committed, on one row however often it comes); one that does was seen now."""
    if not is_open(p):
        log_again("refused", p, path=path, status=p.status)
        db.session.commit()
        return False
    p.last_seen_at = utcnow()
    return True


#: Attempts the exit page makes to get the last events acknowledged before completing anyway.
SAVE_ATTEMPTS = 5


def may_complete(p: Participant, last_seq: int, attempt: int) -> bool:
    """The completion-code rule: a participant completes once the server holds every event up to the last one
    the page logged (``last_seq``); after ``SAVE_ATTEMPTS`` tries (the network is gone) they complete anyway,
    and the missing events are logged."""
    if p.acked_seq >= last_seq:
        return True
    if attempt < SAVE_ATTEMPTS:
        return False
    log("completed_with_missing_events", p, acked_seq=p.acked_seq, last_seq=last_seq)
    return True


def submit_exit(p: Participant, study: Study, answers: dict) -> None:
    """Save the exit survey and complete: the completion code is given, and trials whose events do not show
    the study's minimum work flag the participant for review (with the reason)."""
    save_survey(p, "exit", answers)
    _finish(p, study, "completed", "complete")
    reasons = check_work(p, study)
    if reasons:
        flag(p, "completed without the minimum work: " + "; ".join(reasons))


def check_work(p: Participant, study: Study) -> list[str]:
    """Mark each (non-practice) trial whose events show fewer objects placed or a shorter time than the study's
    minimum (``Trial.review``); returns the reasons. Time is the span of the trial's events on the client's
    clock (simulated participants keep realistic clocks; the server's own times are in the trials table)."""
    work = {trial: (placed or 0, ((last or 0) - (first or 0)) / 1000.0, n) for trial, placed, first, last, n in
            db.session.execute(select(Event.trial, func.sum(case((Event.type.in_(("insert", "replace")), 1),
                                                                     else_=0)),
                                      func.min(Event.client_t), func.max(Event.client_t), func.count())
                               .where(Event.participant_id == p.id).group_by(Event.trial))}
    reasons = []
    for t in trials(p):
        if t.kind != "trial":
            continue
        placed, seconds, n = work.get(t.index, (0, 0.0, 0))
        why = []
        if t.done_at is None:
            why.append("not done")
        if placed < study.min_objects_placed:
            why.append(f"{placed} object(s) placed < {study.min_objects_placed}")
        if seconds < study.min_trial_seconds:
            why.append(f"{seconds:.0f} s of events < {study.min_trial_seconds:g} s" if n else "no events")
        below = below_target(study, t)
        if below:
            why.append(below)
        t.review = ", ".join(why) or None
        if why:
            reasons.append(f"trial {t.index}: {t.review}")
    return reasons


def below_target(study: Study, t: Trial) -> str | None:
    """Why a scored trial is flagged for review under the study's ``[limits] min_target_score`` (None: it is
    not). Flag only: the participant is never told or held back."""
    least = study.min_target_score
    if least is None or t.kind != "trial" or t.score is None or t.score >= least:
        return None
    return f"scene {t.score:.2f} close to the target < {least:g}"


def leave(p: Participant, study: Study) -> None:
    """The participant leaves the study before its end: status ``returned``, with the study's code for it. The
    events and answers given so far stay (the export has them; the analysis counts completed trials only)."""
    _finish(p, study, "returned", "returned")


def completion_url(study: Study, p: Participant) -> str | None:
    """Where the end page sends the participant with their code, whichever way they ended (MTurk's HIT is
    submitted by a form to turkSubmitTo instead, when complete); a pilot is sent nowhere."""
    if study.completion_url and p.code and not p.pilot:
        return study.completion_url.replace("{code}", quote(p.code, safe=""))
    return None
