"""The device check in real browsers: a browser without WebGL — Chromium with WebGL switched off, Firefox without a
GL driver (headless here) — is screened out before consent with a page in the participant's language that names
what is missing, and takes no schedule row; a capable browser's frame rate and GPU are stored; a WebGL context
lost mid-trial is told, and the view goes on when the browser gives it back."""

from __future__ import annotations

import json
import sqlite3

from .engines import FirefoxDriver, require
from .pagehelp import ARGS, ARTIFACTS, CHROMIUM, hook, new_context, ready, screenshot, start, until


def _stored(database, pid: str) -> tuple[str, int, dict]:
    with sqlite3.connect(database) as con:
        status, row, report = con.execute("SELECT status, row, viewport FROM participants WHERE platform_id = ?",
                                          (pid,)).fetchone()
    return status, row, json.loads(report)


def test_chromium_without_webgl_is_screened_out_in_the_participants_language(server):
    from playwright.sync_api import sync_playwright

    base, database = server
    with sync_playwright() as p:
        browser = p.chromium.launch(executable_path=CHROMIUM, args=[*ARGS, "--disable-webgl"])
        for pid, language, says in (("no-gl-en", "en", "WebGL 2 is switched off, blocked or not supported"),
                                    ("no-gl-de", "de", "WebGL 2 ist ausgeschaltet, blockiert")):
            context = browser.new_context(viewport={"width": 1280, "height": 720}, locale=language,
                                          extra_http_headers={"Accept-Language": language})
            page = context.new_page()
            page.goto(f"{base}/study/demo/start?pid={pid}")
            until(page, "document.body.dataset.step === 'done'")
            text = page.inner_text("main")
            assert says in text and "DEMO-SCREENED" in text, text
            screenshot(page, f"screened-out-{language}")
            context.close()
            status, row, report = _stored(database, pid)
            assert (status, row, report["reasons"], report["fps"]) == ("screened_out", -1, ["webgl2"], None)
        browser.close()


def test_firefox_without_a_gl_driver_is_screened_out(server):
    require("firefox")
    base, database = server
    d = FirefoxDriver(display=None)  # headless: Firefox here finds no GL driver at all
    try:
        d.goto(f"{base}/study/demo/start?pid=firefox-no-gl")
        d.until("document.body.dataset.step === 'done'")
        assert "WebGL 2 is switched off" in d.evaluate("document.querySelector('main').innerText")
        d.screenshot(ARTIFACTS / "screened-out-firefox.png")
    finally:
        d.close()
    status, row, report = _stored(database, "firefox-no-gl")
    assert (status, row, report["reasons"]) == ("screened_out", -1, ["webgl2"])


def test_a_capable_browser_passes_with_its_frame_rate_and_gpu_stored(page, server):
    base, database = server
    start(page, base, "capable")
    status, row, report = _stored(database, "capable")
    assert status == "in_progress" and row >= 0 and report["missing"] == [] and report["reasons"] == []
    assert report["fps"] > 0 and "SwiftShader" in report["renderer"]


def test_a_webgl_context_lost_mid_trial_is_told_and_the_view_goes_on_when_it_returns(browser, server):
    base, database = server
    context = new_context(browser)
    page = context.new_page()
    start(page, base, "context-lost")
    frames = hook(page, "frames()")
    hook(page, "loseContext()")
    until(page, "document.getElementById('banner').textContent.includes('the computer reset its graphics')")
    assert page.locator("#banner button").inner_text() == "Reload"
    screenshot(page, "context-lost")
    hook(page, "restoreContext()")
    until(page, "document.getElementById('banner').hidden")
    page.evaluate("() => window.sceneSuggestTest.orbit(300)")
    assert hook(page, "frames()") > frames  # drawing again
    page.reload()  # what the button does: the same trial, the same scene, nothing lost
    ready(page)
    until(page, "window.sceneSuggestTest.pending() === 0")
    with sqlite3.connect(database) as con:
        notes = [m for (m,) in con.execute("SELECT e.payload FROM events e JOIN participants p ON "
                                           "p.id = e.participant_id WHERE p.platform_id = 'context-lost' AND "
                                           "e.type = 'client_error' ORDER BY e.seq")]
        seqs = [s for (s,) in con.execute("SELECT e.seq FROM events e JOIN participants p ON p.id = "
                                          "e.participant_id WHERE p.platform_id = 'context-lost' ORDER BY e.seq")]
    assert ["lost" in n for n in notes] == [True, False] and "restored" in notes[1]
    assert seqs == list(range(len(seqs)))
    context.close()
