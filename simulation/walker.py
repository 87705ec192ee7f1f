"""The participant walk: from the entry link through every page of a study, the one way all simulated
participants, tests and benchmarks go through it.

Each page names its step (:mod:`.page`); the walker answers the steps whose answer is always the same (the
device check, consent, the instruction pages, a condition's instructions) and asks its caller for the rest: the
survey answers (``answers``) and what to do in a trial (``trial``). Every request goes through a transport
(:mod:`.transport`), so the same walk runs in process or over real HTTP.
"""

from __future__ import annotations

from collections.abc import Callable, Collection
from urllib.parse import urlencode

from .page import Page, read_page
from .transport import FlowError

#: The device check's report of a browser that can run the trial (study_server.participants.device): a 1440 × 900
#: window, nothing missing, 60 frames a second.
CAPABLE_DEVICE = {"missing": "", "width": "1440", "height": "900", "pixel_ratio": "1", "touch_only": "false",
                  "fps": "60", "renderer": ""}
#: What a person answers on the pages that ask nothing of them.
FIXED_ANSWERS = {"device": CAPABLE_DEVICE, "consent": {"agree": "yes"},
                 "instructions": {"go": "next"}, "briefing": {"go": "start"}}


def fixed_answer(page: Page) -> dict | None:
    """The form a person sends from a page that asks nothing of them (with the page's own hidden fields, such as
    the trial a condition's instructions are shown for), or None for a page that asks something."""
    if page.step not in FIXED_ANSWERS:
        return None
    return {**page.hidden, **FIXED_ANSWERS[page.step]}


#: Pages a study shows before and after the trials whose answers the caller gives.
SURVEYS = ("demographics", "exit")
#: Where a walk ends: the end page, or the exit survey waiting for events the server has not acknowledged (a
#: browser would send them and try again; a walker that gets there has lost events, which its caller must see).
ENDS = ("done", "saving")
MAX_PAGES = 200


class Walker:
    """One participant's way through the pages of ``study`` over ``http`` (a transport)."""

    def __init__(self, http, study: str):
        self.http, self.study = http, study

    def enter(self, query: str | dict, headers: dict | None = None) -> Page:
        """Follow the entry link (``pid=…``, or a platform's parameters) and read the page it leads to."""
        query = urlencode(query) if isinstance(query, dict) else query
        r = self.http.get(f"/study/{self.study}/start?{query}", headers=headers)
        if r.status >= 400:
            said = read_page(r.body).message
            raise FlowError(f"entry link → {r.status}" + (f": {said}" if said else ""), r.status)
        return read_page(r.body)

    def current(self) -> Page:
        """The page the participant is on now (what a reload shows)."""
        r = self.http.get(f"/study/{self.study}/")
        if r.status >= 400:
            raise FlowError(f"GET /study/{self.study}/ → {r.status}", r.status)
        return read_page(r.body)

    def submit(self, step: str, form: dict, page: Page) -> Page:
        """Post ``form`` to ``step`` with ``page``'s form token; returns the page the answer leads to."""
        r = self.http.post(f"/study/{self.study}/{step}", form={"csrf_token": page.csrf or "", **form})
        if r.status >= 400:
            raise FlowError(f"POST {step} → {r.status}", r.status)
        return read_page(r.body)

    def walk(self, answers: Callable[[Page], dict], trial: Callable[[dict], bool] | None = None,
             until: Collection[str] = ("done",), page: Page | None = None) -> Page:
        """Go from ``page`` (default: the current one) until a step of ``until`` or an end (:data:`ENDS`);
        returns that page.

        ``answers(page)`` gives the form of a survey page (``demographics``, ``exit``); ``trial(boot)`` works
        through the trial whose boot data is given and returns False to stop walking there (a drop-out). A walk
        without ``trial`` stops at the first trial page."""
        page = page or self.current()
        for _ in range(MAX_PAGES):
            if page.step in until or page.step in ENDS:
                return page
            if page.step == "trial":
                if trial is None or not trial(page.boot):
                    return page
                page = self.current()
            elif page.step in FIXED_ANSWERS:
                page = self.submit(page.step, fixed_answer(page), page)
            elif page.step in SURVEYS:
                page = self.submit(page.step, answers(page), page)
            else:
                raise FlowError(f"a page the walk cannot go on from (step {page.step!r})")
        raise FlowError("the study never ended")

    def to_first_trial(self, query: str | dict, answers: Callable[[Page], dict], headers: dict | None = None
                       ) -> Page:
        """From the entry link to the first trial page (or wherever the walk stops before it)."""
        return self.walk(answers, page=self.enter(query, headers))
