"""A browser without WebGL (switched off, blocklisted, no driver) is told on the trial page that it cannot show the
3D editor — in the participant's language — instead of a grey page, and the server hears of it (a client_error
event). (Screening such a browser out before consent is the device check's part.)"""

from __future__ import annotations

import sqlite3

from .pagehelp import ARGS, CHROMIUM, until


def test_a_browser_without_webgl_is_told_so(server):
    from flowhelp import DEMOGRAPHICS
    from playwright.sync_api import sync_playwright

    from simulation.transport import HttpTransport
    from simulation.walker import Walker

    base, database = server
    for pid, headers, said in (("no-webgl", {}, "This browser cannot show the 3D editor: WebGL is switched off"),
                               ("kein-webgl", {"Accept-Language": "de"}, "Dieser Browser kann den 3D-Editor nicht")):
        http = HttpTransport(base)
        assert Walker(http, "demo").to_first_trial({"pid": pid}, lambda _: DEMOGRAPHICS, headers).step == "trial"
        with sync_playwright() as p:
            browser = p.chromium.launch(executable_path=CHROMIUM, args=[*ARGS, "--disable-webgl"])
            context = browser.new_context(viewport={"width": 1280, "height": 720})
            context.add_cookies(http.cookies())
            page = context.new_page()
            page.goto(f"{base}/study/demo/")
            until(page, "document.getElementById('banner') && !document.getElementById('banner').hidden")
            assert page.inner_text("#banner").startswith(said)
            assert page.locator("#editor canvas").count() == 0
            until(page, "document.getElementById('banner').dataset.state === 'saved'")  # the outbox reached it
            browser.close()
        with sqlite3.connect(database) as con:
            (message,) = con.execute("SELECT e.payload FROM events e JOIN participants p ON p.id = e.participant_id "
                                     "WHERE p.platform_id = ? AND e.type = 'client_error'", (pid,)).fetchone()
        assert "no WebGL" in message
