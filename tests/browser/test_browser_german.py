"""A German participant completes the demo in Chromium with every visible string in German: the browser's
language (Accept-Language) chooses among the study's languages at arrival; the pages, the editor's strings, the
survey's errors and the study's own texts follow it. Screenshots of the consent, a trial with suggestions, the exit
survey and the done page are in test-artifacts/."""

from __future__ import annotations

import re

import pytest

from scenesuggest.library.search import split_camel
from study_server.base.i18n import TRANSLATIONS, category_names, check_catalogue
from study_server.studies.study_file import load_study

from .pagehelp import new_context, place_with_suggestions, ready, screenshot, until, walked, walked_to_exit

pytestmark = pytest.mark.browser
GERMAN = {"Accept-Language": "de-DE,de;q=0.9"}


def english(study) -> list[re.Pattern]:
    """What must not show on a German page, as whole words: every English string of the server that German says
    otherwise (the text around a placeholder), and the study's English texts."""
    texts = []
    for m in check_catalogue(TRANSLATIONS / "de" / "LC_MESSAGES" / "messages.po"):
        if m.id and m.string and m.string != m.id:
            texts += [part.strip() for part in re.split(r"%\([a-z_]+\)s|\{[a-z_]+\}", m.id)]
    questions = (*study.demographics, *study.exit_survey)
    texts += [study.title, study.description, *(c.label for c in study.conditions),
              *(c.instructions for c in study.conditions), *(s.title for s in study.scenes.values()),
              *(q.label for q in questions), *(o for q in questions for o in q.options),
              *(e for q in questions for e in (q.low, q.high)),
              *(line for t, body in study.instructions for line in (t, *body.strip().split("\n"))),
              *study.consent_text.strip().split("\n")]
    german = {t.in_language("de") for t in texts if hasattr(t, "in_language")}
    names = category_names("de")  # the corpus's categories, as tiles would name them in English (any case)
    corpus = [re.compile(rf"(?<!\w){re.escape(split_camel(c))}(?!\w)", re.IGNORECASE) for c, n in names.items()
              if n.lower() != split_camel(c).lower()]
    return corpus + [re.compile(rf"(?<!\w){re.escape(str(t))}(?!\w)") for t in {str(t) for t in texts}
                     if len(str(t)) >= 4 and str(t) not in german]


#: Everything a page says, shown or not: its text (the tooltip and the dialog too) and the attributes a reader or
#: a screen reader shows (titles, labels, placeholders, alternatives).
SAID = """() => [document.title, document.body.textContent, ...[...document.querySelectorAll(
    '[title], [aria-label], [placeholder], [alt]')].flatMap((e) => ['title', 'aria-label', 'placeholder', 'alt']
    .map((a) => e.getAttribute(a) || ''))].join('\\n')"""


def in_german(page, study, name: str) -> None:
    assert page.evaluate("() => document.documentElement.lang") == "de", name
    said = page.evaluate(SAID)
    leaked = sorted({p.pattern for p in english(study) if p.search(said)})
    assert not leaked, f"{name}: English on the page: {leaked}"


def _german_browser_at(browser, base: str, http, step: str):
    """A German browser taking over the session ``http`` walked (its cookies), on its current page, ``step``."""
    context = new_context(browser, locale="de-DE")
    context.add_cookies(http.cookies())
    page = context.new_page()
    page.goto(f"{base}/study/demo/")
    until(page, f"document.body.dataset.step === '{step}'")
    return context, page


def test_a_german_participant_sees_the_demo_in_german(server, browser):
    from demostudy import DEMO_STUDY

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
    until(page, "document.body.dataset.step === 'briefing'")
    in_german(page, study, "the practice's condition explained")
    assert "Bevor Sie beginnen" in page.inner_text("main")
    ready(page)
    assert page.inner_text("#hint").startswith("Klicken Sie")  # how to ask, until asked
    response, placed = place_with_suggestions(page)
    in_german(page, study, "trial with suggestions")
    label = page.locator(".suggestions .tile span").first  # long German names break with a hyphen
    assert label.evaluate("e => getComputedStyle(e).hyphens") == "auto"
    assert label.evaluate("e => e.closest('[lang]').lang") == "de"
    assert page.inner_text("#done-button") == "Fertig" and "Übung" in page.inner_text(".trial-title")
    assert page.get_attribute("#target", "aria-label").startswith("Zielszene: ")
    screenshot(page, "de-trial-suggestions")
    context.close()

    http, step = walked(base, "de-change", GERMAN, trials=1)  # past the practice: the interface changes
    assert step == "briefing"
    context, page = _german_browser_at(browser, base, http, "briefing")
    in_german(page, study, "the next condition explained")
    assert "Ab dieser Szene fügen Sie Objekte auf eine andere Art hinzu." in page.inner_text("main")
    screenshot(page, "de-briefing")
    ready(page)
    assert page.evaluate("() => document.documentElement.lang") == "de"
    context.close()

    http = walked_to_exit(base, "de-exit", GERMAN)  # a third German participant, to the exit survey
    context, page = _german_browser_at(browser, base, http, "exit")
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
