"""Participants with any ability: every page a participant or an experimenter sees has no serious or critical
violation of axe-core's WCAG 2.0/2.1 A and AA rules; consent, the surveys and the exit are completed with the keyboard
alone, with the focus visible; pages say their language; the target scene has a text alternative; the editor lists
its keyboard shortcuts."""

from __future__ import annotations

import re

import pytest
from flowhelp import EXIT
from support import ROOT

from .pagehelp import new_context, ready, screenshot, until, walked_to_exit

pytestmark = pytest.mark.browser

AXE = ROOT / "node_modules" / "axe-core" / "axe.min.js"
RULES = ["wcag2a", "wcag2aa", "wcag21a", "wcag21aa"]
RUN = ("async (tags) => (await axe.run(document, {runOnly: {type: 'tag', values: tags}})).violations.map(v => "
       "({id: v.id, impact: v.impact, help: v.help, nodes: v.nodes.slice(0, 5).map(n => n.target.join(' '))}))")


def violations(page) -> list[dict]:
    """axe-core's serious and critical violations of the WCAG 2.x A/AA rules on the page as it is now."""
    if not AXE.exists():
        pytest.fail("axe-core is missing from node_modules (npm ci)")
    if not page.evaluate("() => typeof window.axe !== 'undefined'"):
        page.add_script_tag(path=str(AXE))
    return [v for v in page.evaluate(RUN, RULES) if v["impact"] in ("serious", "critical")]


def check(page, name: str, seen: dict, step: str | None = None) -> None:
    """axe on the page, once it is the one named (its ``data-step``, when given) and says its language."""
    if step is not None:
        until(page, f"document.body && document.body.dataset.step === {step!r}")
    assert page.evaluate("() => document.documentElement.lang") == "en", name
    seen[name] = violations(page)


def test_every_participant_page_passes_axe(server, browser):
    base, _ = server
    seen: dict[str, list] = {}
    context = new_context(browser, bypass_csp=True)  # axe is added to the page as a script
    page = context.new_page()
    page.goto(f"{base}/study/demo/start?pid=axe-1")
    until(page, "document.body.dataset.step === 'consent'")
    check(page, "consent", seen, "consent")
    page.click("text=I agree to take part")
    check(page, "demographics", seen, "demographics")
    page.click("button:has-text('Continue')")  # nothing answered: the errors shown are checked too
    until(page, "!!document.querySelector('.error')")
    check(page, "demographics with errors", seen, "demographics")
    page.fill("input[name=age]", "29")
    page.check("input[name=experience_3d][value='A few times']")
    page.check("input[name=pointing_device][value=Trackpad]")
    page.click("button:has-text('Continue')")
    check(page, "instructions", seen, "instructions")
    while page.locator("button[name=go][value=next]").count():
        if page.inner_text("button[name=go][value=next]") == "Start":  # the last page: the editor's shortcuts
            check(page, "instructions, last page", seen, "instructions")
        page.click("button[name=go][value=next]")
        page.wait_for_load_state()
    until(page, "document.body.dataset.step === 'briefing'")
    check(page, "the condition's instructions", seen, "briefing")
    ready(page)
    check(page, "trial", seen, "trial")
    page.click("#done-button")
    check(page, "trial, done confirmation", seen)
    page.goto(f"{base}/study/demo/leave")
    check(page, "leave", seen, "leave")
    page.goto(f"{base}/study/demo/no-such-page")
    check(page, "message", seen)
    context.close()

    context = new_context(browser, bypass_csp=True)
    context.add_cookies(walked_to_exit(base, "axe-2").cookies())
    page = context.new_page()
    page.goto(f"{base}/study/demo/")
    until(page, "document.body.dataset.step === 'exit'")
    check(page, "exit survey", seen, "exit")
    for name, value in EXIT.items():
        if name == "comments":
            page.fill("textarea[name=comments]", value)
        else:
            page.check(f"input[name={name}][value='{value}']")
    page.click("button:has-text('Continue')")
    page.wait_for_selector(".code")
    check(page, "done", seen)
    context.close()

    context = new_context(browser, bypass_csp=True, user_agent="Mozilla/5.0 (iPhone) Mobile")
    page = context.new_page()
    page.route("**/js/device.js", lambda route: route.abort())  # the check's page stays as it first shows
    page.goto(f"{base}/study/demo/start?pid=axe-3")
    until(page, "document.body.dataset.step === 'device'")
    check(page, "device check", seen, "device")
    page.unroute("**/js/device.js")
    page.reload()
    until(page, "document.body.dataset.step === 'done'")  # a phone is screened out, with its code
    check(page, "screened out", seen)
    context.close()
    assert {k: v for k, v in seen.items() if v} == {}
    assert len(seen) == 14


def test_the_admin_pages_pass_axe(authoring_server, browser):
    base, _ = authoring_server
    walked_to_exit(base, "axe-admin")  # a participant to list, show and replay
    seen: dict[str, list] = {}
    context = new_context(browser, bypass_csp=True)
    page = context.new_page()
    page.goto(f"{base}/admin/login")
    check(page, "login", seen)
    page.fill("input[name=password]", "author-password")
    page.click("button[type=submit]")
    until(page, "location.pathname === '/admin/'")
    check(page, "dashboard", seen)
    page.goto(f"{base}/admin/demo/participants")
    check(page, "participants", seen)
    page.click("table a[href*='/participants/']")
    until(page, "/\\/participants\\/\\d+$/.test(location.pathname)")
    check(page, "participant", seen)
    page.click("a[href$='/replay']")
    until(page, "!!document.querySelector('#events li')")
    check(page, "replay", seen)
    page.goto(f"{base}/admin/demo/preview")
    check(page, "preview grid", seen)
    page.goto(f"{base}/admin/demo/preview/full/bedside")
    ready(page)
    check(page, "preview of a trial", seen)
    page.goto(f"{base}/admin/demo/author/bedside")
    ready(page)
    check(page, "target editor", seen)
    context.close()
    assert {k: v for k, v in seen.items() if v} == {}


def focus_outline(page) -> str:
    """The focused element's outline (style and width), and what it is."""
    return page.evaluate("""() => { const e = document.activeElement, s = getComputedStyle(e);
        return `${s.outlineStyle} ${s.outlineWidth} on ${e.tagName} ${e.name || e.id || e.className}`; }""")


def tab_to(page, selector: str, limit: int = 60) -> None:
    """Press Tab until ``selector`` has the focus, checking that every stop on the way shows it with the pages'
    own focus style (3 px solid: :focus-visible in study.css, not only the browser's default ring)."""
    for _ in range(limit):
        page.keyboard.press("Tab")
        outline = focus_outline(page)
        if not outline.endswith(" on BODY "):  # (the page itself, between the last stop and the first)
            assert outline.startswith("solid 3px"), outline
        if page.evaluate("(s) => document.activeElement && document.activeElement.matches(s)", selector):
            return
    raise AssertionError(f"Tab never reached {selector}")


def choose(page, name: str, value: str) -> None:
    """Select ``value`` of the radio group ``name`` with the keyboard: Tab into the group, arrows to the value."""
    tab_to(page, f"input[name={name}]")
    for _ in range(12):
        if page.evaluate("(n) => document.activeElement.value", name) == value:
            page.keyboard.press("Space")
            return
        page.keyboard.press("ArrowDown")
    raise AssertionError(f"{value!r} is not an option of {name}")


def press_enter_and_wait(page) -> None:
    """Enter on the focused button, which submits its form: wait for the next page."""
    with page.expect_navigation():
        page.keyboard.press("Enter")


def test_consent_surveys_and_the_exit_with_the_keyboard_alone(server, browser):
    base, _ = server
    context = new_context(browser)
    page = context.new_page()
    page.goto(f"{base}/study/demo/start?pid=keys-1")
    until(page, "document.body.dataset.step === 'consent'")
    tab_to(page, "button[name=agree][value=yes]")
    press_enter_and_wait(page)
    until(page, "document.body.dataset.step === 'demographics'")
    tab_to(page, "input[name=age]")
    page.keyboard.type("29")
    choose(page, "experience_3d", "A few times")
    choose(page, "pointing_device", "Trackpad")
    tab_to(page, "button[type=submit]")
    press_enter_and_wait(page)
    assert page.evaluate("() => document.body.dataset.step") == "instructions"
    while page.locator("button[name=go][value=next]").count():
        tab_to(page, "button[name=go][value=next]")
        press_enter_and_wait(page)
    assert page.evaluate("() => document.body.dataset.step") == "briefing"
    assert page.evaluate("() => document.activeElement.value") == "start"  # focused: Enter starts the trial
    press_enter_and_wait(page)
    ready(page)
    screenshot(page, "trial-by-keyboard")
    shortcuts = page.inner_text(".help-text")
    for key in ("Q", "E", "Shift", "Delete", "Ctrl+Z", "Ctrl+Shift+Z", "Esc"):
        assert re.search(rf"(^|\W){re.escape(key)}(\W|$)", shortcuts), key
    assert page.get_attribute("#undo-button", "aria-keyshortcuts") == "Control+Z"
    target = page.get_attribute("#target", "aria-label")
    assert target.startswith("Target scene:") and len(target) > len("Target scene:") + 3, target
    context.close()

    context = new_context(browser)
    context.add_cookies(walked_to_exit(base, "keys-2").cookies())
    page = context.new_page()
    page.goto(f"{base}/study/demo/")
    until(page, "document.body.dataset.step === 'exit'")
    for name, value in EXIT.items():
        if name == "comments":
            tab_to(page, "textarea[name=comments]")
            page.keyboard.type(value)
        else:
            choose(page, name, value)
    tab_to(page, "button[type=submit]")
    press_enter_and_wait(page)
    page.wait_for_selector(".code")
    assert page.inner_text(".code")
    context.close()
