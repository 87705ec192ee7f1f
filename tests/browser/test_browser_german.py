"""A German participant completes the demo in Chromium with every visible string in German: the browser's
language (Accept-Language) chooses among the study's languages at arrival; the pages, the editor's strings, the
survey's errors and the study's own texts follow it. Screenshots of the consent, a trial with suggestions, the exit
survey and the done page are in test-artifacts/."""

from __future__ import annotations

import pytest
from flowhelp import DEMOGRAPHICS

from simulation.transport import HttpTransport
from simulation.walker import Walker
from study_server.i18n import TRANSLATIONS, check_catalogue
from study_server.study_file import load_study

from .conftest import new_context
from .pagehelp import place_with_suggestions, ready, screenshot, until

pytestmark = pytest.mark.browser
GERMAN = {"Accept-Language": "de-DE,de;q=0.9"}


def english(study) -> list[str]:
    """Texts that must not show on a German page: the server's English strings and the study's English texts
    (long enough not to be German too)."""
    catalogue = [m.id for m in check_catalogue(TRANSLATIONS / "de" / "LC_MESSAGES" / "messages.po")
                 if m.id and m.string != m.id and len(m.id) >= 12 and "%(" not in m.id and "{" not in m.id]
    texts = [study.title, study.consent_text.strip().split("\n")[0], *(c.label for c in study.conditions),
             *(q.label for q in (*study.demographics, *study.exit_survey)), *(t for t, _ in study.instructions)]
    return catalogue + [str(t) for t in texts if len(str(t)) >= 12]


def in_german(page, study, name: str) -> None:
    assert page.evaluate("() => document.documentElement.lang") == "de", name
    shown = page.inner_text("body")
    leaked = [t for t in english(study) if t in shown]
    assert not leaked, f"{name}: English on the page: {leaked}"


def test_a_german_participant_sees_the_demo_in_german(server, browser):
    from conftest import DEMO_STUDY

    base, _ = server
    study = load_study(DEMO_STUDY)
    context = new_context(browser, locale="de-DE")
    page = context.new_page()
    page.goto(f"{base}/study/demo/start?pid=de-browser")
    until(page, "document.body.dataset.step === 'consent'")
    in_german(page, study, "consent")
    assert "Dies ist die Vorführung" in page.inner_text("main")
    screenshot(page, "de-consent")
    page.click("button[name=agree][value=yes]")
    page.click("button[type=submit]")  # nothing answered: the survey's errors in German
    until(page, "!!document.querySelector('.error')")
    in_german(page, study, "demographics with errors")
    assert "Bitte beantworten Sie diese Frage." in page.inner_text("main")
    page.fill("input[name=age]", "29")
    page.check("input[name=experience_3d][value='A few times']")  # shown as "Ein paar Mal", stored as given
    page.check("input[name=pointing_device][value=Trackpad]")
    page.click("button[type=submit]")
    until(page, "document.body.dataset.step === 'instructions'")
    while page.locator("button[name=go][value=next]").count():
        in_german(page, study, "instructions")
        page.click("button[name=go][value=next]")
        page.wait_for_load_state()
    ready(page)
    response, placed = place_with_suggestions(page)
    in_german(page, study, "trial with suggestions")
    assert page.inner_text("#done-button") == "Fertig" and "Übung" in page.inner_text(".trial-title")
    assert page.get_attribute("#target", "aria-label").startswith("Zielszene: ")
    screenshot(page, "de-trial-suggestions")
    context.close()

    http = HttpTransport(base)  # a second German participant walked to the exit survey over HTTP
    walker = Walker(http, "demo")
    seq = 0

    def trial(b: dict) -> bool:
        nonlocal seq
        t, auth = b["trial"], {"Authorization": f"Bearer {b['token']}"}
        events = [{"seq": seq, "t": 1.0e12 + seq, "type": "trial_start", "trial": t["index"],
                   "payload": {"scene": t["scene"], "condition": t["condition"]}},
                  {"seq": seq + 1, "t": 1.0e12 + seq + 12000, "type": "trial_done", "trial": t["index"],
                   "payload": {"objects": 0}}]
        seq += 2
        assert http.post("/api/events", json_body={"page_id": "walk", "events": events}, headers=auth).status == 200
        assert http.post("/api/trial/done", json_body={"trial": t["index"]}, headers=auth).status == 200
        return True

    assert walker.walk(lambda _: DEMOGRAPHICS, trial, until=("exit",),
                       page=walker.enter({"pid": "de-exit"}, headers=GERMAN)).step == "exit"
    context = new_context(browser, locale="de-DE")
    context.add_cookies(http.cookies())
    page = context.new_page()
    page.goto(f"{base}/study/demo/")
    until(page, "document.body.dataset.step === 'exit'")
    in_german(page, study, "exit survey")
    screenshot(page, "de-exit")
    for name, value in (("enjoy_list", "4"), ("competent_list", "4"), ("enjoy_suggestions", "5"),
                        ("competent_suggestions", "5"), ("preference", "Suggestions, oriented")):
        page.check(f"input[name={name}][value='{value}']")
    page.click("button[type=submit]")
    page.wait_for_selector(".code")
    in_german(page, study, "done")
    assert "Vielen Dank!" in page.inner_text("main")
    screenshot(page, "de-done")
    context.close()
