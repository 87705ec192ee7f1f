"""The participant's editor in a real browser: Playwright driving Debian's Chromium (WebGL on SwiftShader) against
the study server run as `make serve` runs it. Clicks land on real pixels of real objects (the page's test hook
converts world points to pixels); the database is compared with what the page logged."""

from __future__ import annotations

import json
import math
import re
import shutil
import sqlite3
import time
from pathlib import Path

import numpy as np
import pytest
from conftest import IN_CI, ROOT, copy_demo_study, gunicorn, make_app
from PIL import Image

CHROMIUM = shutil.which("chromium") or "/usr/bin/chromium"
ARGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
        "--disable-background-networking", "--disable-component-update", "--disable-sync",
        "--enable-unsafe-swiftshader", "--use-angle=swiftshader"]
ARTIFACTS = ROOT / "test-artifacts"


def _require_browser():
    try:
        import playwright  # noqa: F401
    except ImportError:
        pytest.fail("playwright is not installed") if IN_CI else pytest.skip("playwright is not installed")
    if not Path(CHROMIUM).exists():
        message = "Chromium is not installed (apt-get install chromium)"
        pytest.fail(message + " — required under CI=true") if IN_CI else pytest.skip(message)


@pytest.fixture(scope="module")
def server(tmp_path_factory, demo_resources):
    """gunicorn with 2 workers on a fresh SQLite database; yields (base URL, database path)."""
    _require_browser()
    with gunicorn(tmp_path_factory.mktemp("browser")) as running:
        yield running


@pytest.fixture(scope="module")
def browser(server):
    from playwright.sync_api import sync_playwright

    with sync_playwright() as p:  # launch() gives the browser a fresh temporary profile
        b = p.chromium.launch(executable_path=CHROMIUM, args=ARGS)
        yield b
        b.close()


IGNORED_CONSOLE = ("GPU stall due to ReadPixels", "favicon", "dbus")
TEST_HOOK = "window.sceneSuggestTestHook = true"  # set before the page's scripts: trial.js then loads test-hook.js


def new_context(browser, test_hook: bool = True, **options):
    """A browser context whose pages load the trial page's test hook (``window.sceneSuggestTest``) unless
    ``test_hook`` is false, as a participant's page does not."""
    context = browser.new_context(viewport={"width": 1280, "height": 720}, **options)
    if test_hook:
        context.add_init_script(TEST_HOOK)
    return context


@pytest.fixture
def page(browser):
    context = new_context(browser)
    pg = context.new_page()
    pg.console_problems = []
    pg.on("console", lambda m: m.type == "error" and not any(s in m.text for s in IGNORED_CONSOLE)
          and pg.console_problems.append(m.text))
    pg.on("pageerror", lambda e: pg.console_problems.append(str(e)))
    yield pg
    context.close()


def until(page, expression: str, timeout: float = 20.0):
    """Poll a JS expression (the page's CSP forbids Playwright's eval-based waiting)."""
    from playwright.sync_api import Error

    end = time.time() + timeout
    while time.time() < end:
        try:
            value = page.evaluate(f"() => {expression}")
        except Error:  # the page is navigating
            value = None
        if value:
            return value
        time.sleep(0.05)
    raise AssertionError(f"timed out waiting for {expression}")


def hook(page, expression: str):
    return page.evaluate(f"() => window.sceneSuggestTest.{expression}")


def ready(page):
    until(page, "!!(window.sceneSuggestTest && window.sceneSuggestTest.ready)")
    page.evaluate("() => window.sceneSuggestTest.loaded()")


def start(page, base: str, pid: str, study: str = "demo"):
    page.goto(f"{base}/study/{study}/start?pid={pid}")
    page.click("text=I agree to take part")
    page.fill("input[name=age]", "29")
    page.check("input[name=experience_3d][value='A few times']")
    page.check("input[name=pointing_device][value=Trackpad]")
    page.click("button:has-text('Continue')")
    while page.locator("button[name=go][value=next]").count():
        page.click("button[name=go][value=next]")
    ready(page)


def objects(page) -> dict:
    return {o["id"]: o for o in hook(page, "objects()")}


def floor_pixel(page, x=0.0, z=0.3):
    return hook(page, f"worldToPixel({x}, 0, {z})")


def heading_deg(transform, face="bottom"):
    """Yaw of the front (+Z column of the column-major matrix) about +Y, degrees in [0, 360)."""
    fx, fz = transform[8], transform[10]
    return math.degrees(math.atan2(fx, fz)) % 360


def suggest_at(page, x, y, shift=True):
    before = hook(page, "lastSuggest?.list_id") or None
    if shift:
        page.keyboard.down("Shift")
    page.mouse.click(x, y)
    if shift:
        page.keyboard.up("Shift")
    until(page, f"window.sceneSuggestTest.lastSuggest && window.sceneSuggestTest.lastSuggest.list_id !== {before!r}"
          .replace("None", "null"))
    page.evaluate("() => window.sceneSuggestTest.loaded()")
    return hook(page, "lastSuggest")


def done(page):
    page.click("#done-button")
    with page.expect_navigation(timeout=30000):
        page.click("#confirm-yes")


def exit_survey(page, likert: str, preference: str) -> str:
    """Answer every Likert item with ``likert``, choose ``preference``, submit; returns the completion code."""
    for q in ("enjoy_list", "competent_list", "enjoy_suggestions", "competent_suggestions"):
        page.check(f"input[name={q}][value='{likert}']")
    page.check(f"input[name=preference][value='{preference}']")
    page.click("button:has-text('Continue')")
    page.wait_for_selector(".code")
    return page.inner_text(".code")


def db_events(database: Path, pid: str) -> list[tuple[int, str]]:
    with sqlite3.connect(database) as conn:
        return conn.execute("SELECT e.seq, e.type FROM events e JOIN participants p ON p.id = e.participant_id "
                            "WHERE p.platform_id = ? ORDER BY e.seq", (pid,)).fetchall()


def screenshot(page, name: str):
    ARTIFACTS.mkdir(exist_ok=True)
    page.screenshot(path=str(ARTIFACTS / f"{name}.png"))


def place_with_suggestions(page, mode_toggle=False):
    """Ask for suggestions on the floor; the top one is placed at once on the clicked surface."""
    x, y = floor_pixel(page, -0.6, 0.4)
    if mode_toggle:
        page.click("#suggest-mode")
    response = suggest_at(page, x, y, shift=not mode_toggle)
    if mode_toggle:
        page.click("#suggest-mode")
    placed = [o for o in objects(page).values() if o["parent"] == response["hit"]["parent"] and o["id"] != "room"]
    top = response["suggestions"][0]
    newest = placed[-1]
    assert newest["category"] == top["category"] and newest["model_id"] == top["models"][0]["id"]
    assert newest["parent"] == "room" and newest["surface_type"] == "up_interior"
    assert math.dist(newest["contact_point"], response["hit"]["point"]) < 1e-6  # on the clicked point
    return response, newest


def run_none_trial(page):
    # from the fixed list: the first model, then a click on the floor
    page.click(".side-panel .tile >> nth=0")
    x, y = floor_pixel(page, 0.6, 0.2)
    page.mouse.click(x, y)
    until(page, "window.sceneSuggestTest.objects().length === 2")
    # by search: a lamp
    page.fill(".side-panel input[type=search]", "lamp")
    until(page, "document.querySelector('.side-panel .tile[data-model]') && "
                "document.querySelector('.side-panel .tile[data-model]').dataset.model.includes('Lamp')")
    page.click(".side-panel .tile >> nth=0")
    x, y = floor_pixel(page, -0.6, 0.2)
    page.mouse.click(x, y)
    until(page, "window.sceneSuggestTest.objects().length === 3")
    placed = [o for o in objects(page).values() if o["id"] != "room"]
    assert any("Lamp" in o["category"] for o in placed)
    assert all(abs(heading_deg(o["transform"])) < 1e-6 for o in placed)  # canonical pose
    return placed


def move_rotate_delete_undo(page):
    """Drag an object across the floor, turn it, delete it and undo the deletion."""
    obj = [o for o in objects(page).values() if o["id"] != "room"][-1]
    page.evaluate("() => window.sceneSuggestTest.loaded()")
    grab = hook(page, f"grabPixel({obj['id']!r})")
    assert grab, f"no visible pixel of {obj['category']} to grab"
    x0, y0 = grab
    x1, y1 = floor_pixel(page, 0.0, 1.2)
    page.mouse.move(x0, y0)
    page.mouse.down()
    for k in range(1, 11):
        page.mouse.move(x0 + (x1 - x0) * k / 10, y0 + (y1 - y0) * k / 10)
    page.mouse.up()
    moved = objects(page)[obj["id"]]
    assert math.dist(moved["contact_point"], obj["contact_point"]) > 0.3
    before = heading_deg(moved["transform"])
    page.keyboard.press("e")
    turned = objects(page)[obj["id"]]
    assert abs(((heading_deg(turned["transform"]) - before + 180) % 360) - 180) == pytest.approx(15, abs=0.01)
    # the ring: grab it at the front (0°) and drag it a quarter turn round the object
    start_deg = heading_deg(turned["transform"])
    path = [hook(page, f"ringPixel({a})") for a in range(0, 91, 10)]
    page.mouse.move(*path[0])
    page.mouse.down()
    for px in path[1:]:
        page.mouse.move(*px)
    page.mouse.up()
    ringed = objects(page)[obj["id"]]
    assert abs(((heading_deg(ringed["transform"]) - start_deg + 180) % 360) - 180) == pytest.approx(90, abs=3)
    assert hook(page, "events.at(-1).type") == "rotate_end"
    page.keyboard.press("Delete")
    assert obj["id"] not in objects(page)
    page.keyboard.press("Control+z")
    assert obj["id"] in objects(page)
    page.evaluate("() => window.sceneSuggestTest.loaded()")
    grab = hook(page, f"grabPixel({obj['id']!r})")
    assert grab, (obj, hook(page, f"pickAt(...window.sceneSuggestTest.centrePixel({obj['id']!r}))"))
    x, y = grab
    page.mouse.click(x, y)  # a click on an object selects it …
    assert hook(page, "events.at(-1).payload") == {"object": obj["id"]}
    x, y = floor_pixel(page, 1.5, -1.5)
    page.mouse.click(x, y)  # … and one on empty floor deselects
    assert hook(page, "events.at(-1).type") == "select" and hook(page, "events.at(-1).payload.object") is None


def test_a_whole_participant_run(page, server):
    base, database = server
    pid = "browser-run"
    start(page, base, pid)
    seen = set()
    conditions = []
    while True:
        cond = hook(page, "condition")
        trial = hook(page, "trial")
        conditions.append(cond)
        shoot = cond not in seen and trial >= 0
        if cond == "none":
            assert page.locator(".side-panel .tile").count() == 118
            run_none_trial(page)
            if shoot:
                screenshot(page, f"condition-{cond}")
            move_rotate_delete_undo(page)
        else:
            response, placed = place_with_suggestions(page, mode_toggle=(trial % 2 == 1))
            if cond == "full":  # oriented as the engine said
                engine_heading = response["suggestions"][0]["heading_deg"] % 360
                assert heading_deg(placed["transform"]) == pytest.approx(engine_heading, abs=0.01)
            else:  # canonical pose
                assert heading_deg(placed["transform"]) == pytest.approx(0, abs=1e-6)
            if shoot:
                screenshot(page, f"condition-{cond}")
            # another suggestion replaces it in place
            second = response["suggestions"][1]
            page.click(f".suggestions .tile[data-rank='2'][data-category='{second['category']}']")
            replaced = [o for o in objects(page).values() if o["id"] not in ("room", placed["id"])]
            assert placed["id"] not in objects(page) and replaced[-1]["category"] == second["category"]
            assert math.dist(replaced[-1]["contact_point"], placed["contact_point"]) < 1e-9
            if cond not in seen:
                page.click(".suggestions button.close")
                move_rotate_delete_undo(page)
        if shoot:
            seen.add(cond)
        done(page)
        if "Almost done" in page.content():
            break
        ready(page)
    assert sorted(conditions[1:]) == sorted(["none", "basic", "full"] * 3) and conditions[0] == "full"
    page.fill("textarea[name=comments]", "The suggestions were handy.")
    assert exit_survey(page, "4", "Suggestions, oriented") == "DEMO-DONE-7F3A"
    events = db_events(database, pid)
    seqs = [s for s, _ in events]
    assert seqs == list(range(len(seqs)))  # every event stored once, none missing
    types = {t for _, t in events}
    assert {"trial_start", "trial_done", "context_query", "list_shown", "insert", "replace", "move_start", "move_end",
            "rotate_start", "rotate_end", "delete", "undo", "search", "select", "pointer"} <= types
    assert not page.console_problems, page.console_problems


def test_a_moving_view_may_drop_resolution_and_is_sharp_again_when_still(page, server):
    base, _ = server
    start(page, base, "browser-resolution")
    sharp = hook(page, "resolution()")
    assert sharp["buffer"] == sharp["css"] and sharp["scale"] == 1
    page.evaluate("() => window.sceneSuggestTest.setSlowFrameMs(0)")  # every moving frame counts as slow
    result = page.evaluate("() => window.sceneSuggestTest.orbit(600)")
    assert result["scale"] == pytest.approx(0.7) and result["fps"] > 0
    page.wait_for_timeout(400)  # the camera has been still for longer than the settle time
    after = hook(page, "resolution()")
    assert after == sharp
    x, y = floor_pixel(page)  # picking still maps pixels to the world at full resolution
    assert hook(page, f"pickAt({x}, {y})")["room"]


def test_reload_in_the_middle_of_a_trial_resumes_without_loss(page, server):
    base, database = server
    pid = "browser-reload"
    start(page, base, pid)
    place_with_suggestions(page)
    before_objects = objects(page)
    logged = hook(page, "events.map(e => [e.seq, e.type])")
    page.reload()
    ready(page)
    assert objects(page).keys() == before_objects.keys()
    assert hook(page, "trial") == -1
    x, y = floor_pixel(page, 0.8, -0.5)
    suggest_at(page, x, y)
    logged += hook(page, "events.map(e => [e.seq, e.type])")
    until(page, "window.sceneSuggestTest.pending() === 0")
    stored = [list(e) for e in db_events(database, pid)]
    assert [s for s, _ in stored] == list(range(len(stored)))  # nothing lost, nothing twice
    assert all(e in stored for e in logged)  # everything the page logged, including what it sent while unloading
    assert {"resume", "visibility"} <= {t for _, t in stored}


def test_offline_for_a_while_then_every_event_arrives_once(page, server):
    base, database = server
    pid = "browser-offline"
    start(page, base, pid)
    place_with_suggestions(page)
    until(page, "window.sceneSuggestTest.pending() === 0")
    page.context.set_offline(True)
    obj = [o for o in objects(page).values() if o["id"] != "room"][-1]
    x, y = hook(page, f"grabPixel({obj['id']!r})")
    page.mouse.click(x, y)  # select
    for _ in range(6):
        page.keyboard.press("q")
    page.keyboard.press("Control+z")
    time.sleep(2.5)
    assert hook(page, "pending()") > 0
    assert "Connection lost" in page.inner_text("#banner")
    page.context.set_offline(False)
    until(page, "window.sceneSuggestTest.pending() === 0", timeout=60)
    logged = sorted(tuple(e) for e in hook(page, "events.map(e => [e.seq, e.type])"))
    assert [tuple(e) for e in db_events(database, pid)] == logged
    assert not page.is_visible("#banner") or "Connection lost" not in page.inner_text("#banner")


def test_while_the_server_cannot_store_the_outbox_keeps_every_event(page, server):
    """The server answers 503 (its database full or read-only) for a while: the page keeps the events and sends
    them once the server stores again."""
    base, database = server
    pid = "browser-503"
    start(page, base, pid)
    place_with_suggestions(page)
    until(page, "window.sceneSuggestTest.pending() === 0")
    refused = []

    def full(route):
        refused.append(route.request.url)
        route.fulfill(status=503, content_type="application/json", headers={"Retry-After": "5"},
                      body='{"error": "the study\'s database cannot store data right now", "field": null}')
    page.route("**/api/events", full)
    obj = [o for o in objects(page).values() if o["id"] != "room"][-1]
    x, y = hook(page, f"grabPixel({obj['id']!r})")
    page.mouse.click(x, y)
    for _ in range(4):
        page.keyboard.press("e")
    until(page, "window.sceneSuggestTest.pending() > 0")
    page.wait_for_timeout(3000)  # (a plain sleep would not let Playwright answer the routed requests)
    assert refused and hook(page, "pending()") > 0
    page.unroute("**/api/events", full)
    until(page, "window.sceneSuggestTest.pending() === 0", timeout=60)
    logged = sorted(tuple(e) for e in hook(page, "events.map(e => [e.seq, e.type])"))
    assert [tuple(e) for e in db_events(database, pid)] == logged


def test_a_model_that_fails_to_load_offers_a_retry(page, server):
    base, _ = server
    fail = {"on": True}

    def glb(route):
        if fail["on"] and "GarbageCan" in route.request.url:
            route.abort()
        else:
            route.continue_()
    page.route(re.compile(r".*\.glb$"), glb)
    start(page, base, "browser-retry")
    x, y = floor_pixel(page, 0.0, 0.0)
    page.click("#suggest-mode")
    response = suggest_at(page, x, y, shift=False)
    assert response["suggestions"][0]["category"] == "GarbageCan"  # the demo's top pick on this floor spot
    until(page, "!document.getElementById('banner').hidden")
    assert "did not load" in page.inner_text("#banner")
    screenshot(page, "model-retry")
    fail["on"] = False
    page.click("#banner button")
    until(page, "document.getElementById('banner').hidden")


def test_a_second_tab_takes_over_and_nothing_is_numbered_twice(page, server):
    base, database = server
    pid = "browser-tabs"
    start(page, base, pid)
    place_with_suggestions(page)
    second = page.context.new_page()
    second.goto(f"{base}/study/demo/")
    ready(second)
    until(page, "document.body.classList.contains('inactive')")
    assert "another tab" in page.inner_text("#banner")
    x, y = second.evaluate("() => window.sceneSuggestTest.worldToPixel(0.8, 0, -0.5)")
    second.keyboard.down("Shift")
    second.mouse.click(x, y)
    second.keyboard.up("Shift")
    until(second, "window.sceneSuggestTest.objects().length === 3")  # the first tab's object came along
    until(second, "window.sceneSuggestTest.pending() === 0")
    seqs = [s for s, _ in db_events(database, pid)]
    assert seqs == list(range(len(seqs)))
    logged = [e[0] for e in hook(page, "events.map(e => [e.seq])")] + \
        [e[0] for e in second.evaluate("() => window.sceneSuggestTest.events.map(e => [e.seq])")]
    assert len(logged) == len(set(s for s in logged if s >= 0))


def test_only_a_page_that_asks_for_the_test_hook_loads_it(page, browser, server):
    """A participant's page neither loads the test hook nor keeps its events for it; a test's page does."""
    base, _ = server
    start(page, base, "browser-hook")
    scripts = "performance.getEntriesByType('resource').map(r => r.name).filter(n => n.endsWith('.js'))"
    assert any(n.endswith("/js/test-hook.js") for n in page.evaluate(f"() => {scripts}"))
    plain = new_context(browser, test_hook=False, storage_state=page.context.storage_state())
    try:
        participant = plain.new_page()
        requested = []
        participant.on("request", lambda r: requested.append(r.url))
        participant.goto(f"{base}/study/demo/")
        until(participant, "document.getElementById('hint').textContent !== ''")  # the condition is wired: after
        until(participant, "document.querySelector('#editor canvas')")           # the hook would have loaded
        assert participant.evaluate("() => typeof window.sceneSuggestTest") == "undefined"
        loaded = participant.evaluate(f"() => {scripts}")
        assert any(n.endswith("/js/trial.js") for n in loaded)
        assert not [u for u in requested + loaded if "test-hook" in u]
    finally:
        plain.close()


def db_event_times(database: Path, pid: str) -> list[tuple[int, str, float]]:
    with sqlite3.connect(database) as conn:
        return conn.execute("SELECT e.seq, e.type, e.client_t FROM events e JOIN participants p ON "
                            "p.id = e.participant_id WHERE p.platform_id = ? ORDER BY e.seq", (pid,)).fetchall()


def test_events_whose_seqs_another_sender_took_are_renumbered_never_lost(page, server):
    """Someone (another browser with the token, a tab that numbered alike) stores other events under the seqs
    the page is about to use: the server answers 409, the page sends its events under the seqs it is given."""
    import requests

    base, database = server
    pid = "browser-conflict"
    start(page, base, pid)
    until(page, "window.sceneSuggestTest.pending() === 0")
    token = page.evaluate("() => JSON.parse(document.getElementById('boot').textContent).token")
    acked = len(db_event_times(database, pid)) - 1
    foreign = [{"seq": acked + 1 + i, "t": 1.0 + i, "type": "search", "trial": -1, "payload": {"text": f"x{i}"}}
               for i in range(4)]
    r = requests.post(f"{base}/api/events", json={"page_id": "elsewhere", "events": foreign},
                      headers={"Authorization": f"Bearer {token}"}, timeout=10)
    assert r.ok
    place_with_suggestions(page)  # the page numbers these from acked + 1: taken
    until(page, "window.sceneSuggestTest.pending() === 0", timeout=60)
    stored = db_event_times(database, pid)
    assert [s for s, _, _ in stored] == list(range(len(stored)))
    logged = hook(page, "events.map(e => e.type)")
    mine = [t for _, t, client_t in stored if client_t > 1000]  # the page's own events (real clock)
    assert sorted(mine) == sorted(logged) and len([t for t in stored if t[2] < 1000]) == 4
    with sqlite3.connect(database) as conn:
        assert conn.execute("SELECT COUNT(*) FROM session_log WHERE kind = 'event_conflict'").fetchone()[0] >= 1


def test_a_tab_that_overwrites_the_shared_outbox_cannot_erase_this_pages_events(page, server):
    """Two tabs read and write one localStorage entry: the other tab's write drops this page's pending events
    from it. The page still holds its own events in memory until the server acknowledges them."""
    base, database = server
    pid = "browser-overwrite"
    start(page, base, pid)
    until(page, "window.sceneSuggestTest.pending() === 0")
    page.route("**/api/events", lambda route: route.abort())  # nothing reaches the server for a while
    place_with_suggestions(page)
    assert hook(page, "pending()") > 0
    page.evaluate("""() => {
      const boot = JSON.parse(document.getElementById('boot').textContent);
      const key = `scenesuggest-outbox-${boot.study}-${boot.token.slice(-12)}`;
      const state = JSON.parse(localStorage.getItem(key));
      localStorage.setItem(key, JSON.stringify({ nextSeq: state.nextSeq, acked: state.acked, pending: [] }));
    }""")
    page.unroute("**/api/events")
    page.evaluate("() => window.dispatchEvent(new Event('online'))")
    until(page, "window.sceneSuggestTest.pending() === 0", timeout=60)
    stored = db_event_times(database, pid)
    assert [s for s, _, _ in stored] == list(range(len(stored)))
    assert sorted(t for _, t, _ in stored) == sorted(hook(page, "events.map(e => e.type)"))


def test_an_excluded_participants_page_says_the_session_has_ended(page, server):
    """The experimenter excludes a participant mid-trial: the page's next query and events get 410, it stops
    sending and says so, and its Continue leads to the calm end page."""
    base, database = server
    pid = "browser-excluded"
    start(page, base, pid)
    until(page, "window.sceneSuggestTest.pending() === 0")
    with sqlite3.connect(database) as conn:
        conn.execute("UPDATE participants SET status = 'excluded', excluded_reason = 'test' WHERE platform_id = ?",
                     (pid,))
    x, y = floor_pixel(page, -0.6, 0.4)
    page.keyboard.down("Shift")
    page.mouse.click(x, y)  # a query (410) and its events (410)
    page.keyboard.up("Shift")
    until(page, "document.getElementById('banner').textContent.includes('This session has ended')", timeout=30)
    page.click("#banner button")
    page.wait_for_selector("text=This session has ended")
    assert "Traceback" not in page.content()


# --- the replication study and the admin's scene editor --------------------------------------------------------
@pytest.fixture(scope="module")
def replication_server(tmp_path_factory, replication):
    """gunicorn serving the SceneSuggest replication (Stanford representatives) on a fresh SQLite database."""
    from serverproc import StudyServer

    _require_browser()
    tmp = tmp_path_factory.mktemp("replication")
    make_app(tmp, f"sqlite:///{tmp / 'study.sqlite3'}", studies=[replication])
    with StudyServer(tmp / "instance", f"sqlite:///{tmp / 'study.sqlite3'}", migrate=False, study=replication) as s:
        yield s.base


def test_a_person_completes_the_replication(page, replication_server):
    """Consent, practice and nine trials of the replication with the paper's models: in each, one object placed
    (the top suggestion on a shift-click; a model from the list in `none`), then done; the survey; the code."""
    start(page, replication_server, "replication-run", study="scenesuggest-2015")
    conditions, scenes, shot = [], set(), set()
    while True:
        cond = hook(page, "condition")
        conditions.append(cond)
        target = page.evaluate("() => fetch('/api/scenes/' + JSON.parse(document.getElementById('boot').textContent)"
                               ".trial.scene + '?which=target', {headers: {Authorization: 'Bearer ' + JSON.parse("
                               "document.getElementById('boot').textContent).token}}).then(r => r.json())")
        scenes.add(target["id"])
        if cond == "none":
            assert page.locator(".side-panel .tile").count() == 100
            page.click(".side-panel .tile >> nth=0")
            x, y = floor_pixel(page, 0.5, 0.5)
            page.mouse.click(x, y)
            until(page, "window.sceneSuggestTest.objects().length === 2")
        else:
            x, y = floor_pixel(page, 0.5, 0.5)
            response = suggest_at(page, x, y)
            assert response["suggestions"] and len(objects(page)) == 2
            assert page.evaluate("""() => {  // the panel and its tiles fit on screen, long names and all
              const p = document.querySelector('.suggestions'), t = p.querySelector('.tiles');
              const r = p.getBoundingClientRect();
              return t.scrollWidth <= t.clientWidth + 1 && r.left >= 0 && r.right <= innerWidth
                && r.bottom <= innerHeight; }""")
        if cond not in shot and hook(page, "trial") >= 0:
            page.evaluate("() => window.sceneSuggestTest.loaded()")
            screenshot(page, f"replication-{cond}")
            shot.add(cond)
        done(page)
        if "Almost done" in page.content():
            break
        ready(page)
    assert conditions[0] == "full" and sorted(conditions[1:]) == sorted(["none", "basic", "full"] * 3)
    assert len(scenes) == 4  # the practice scene and the three scenes of this participant's period
    assert exit_survey(page, "3", "Suggestions") == "SS2015-DONE"
    assert not page.console_problems, page.console_problems


@pytest.fixture
def authoring_server(tmp_path, demo_resources):
    """gunicorn serving a copy of the demo study (its targets get written) with an admin password."""
    from serverproc import StudyServer
    from werkzeug.security import generate_password_hash

    _require_browser()
    folder = copy_demo_study(tmp_path).parent
    make_app(tmp_path, f"sqlite:///{tmp_path / 'study.sqlite3'}", studies=[folder / "study.toml"])
    server = StudyServer(tmp_path / "instance", f"sqlite:///{tmp_path / 'study.sqlite3'}", migrate=False,
                         study=folder / "study.toml")
    server.env["SCENESUGGEST_ADMIN_PASSWORD_HASH"] = generate_password_hash("author-password")
    with server:
        yield server.base, folder


def test_an_experimenter_authors_a_target_scene(page, authoring_server):
    """Log in, open a target in the editor, add an object with a suggestion, move nothing else, save it, render
    its image: the scene file has the new object, the PNG shows the scene, and participants are served it."""
    base, folder = authoring_server
    page.goto(f"{base}/admin/login")
    page.fill("input[name=password]", "author-password")
    page.click("button[type=submit]")
    page.goto(f"{base}/admin/demo/preview")
    page.click("a[href='/admin/demo/author/bedside']")
    ready(page)
    assert "Editing target" in page.inner_text(".trial-title") and page.locator("#done-button").count() == 0
    before = objects(page)
    assert len(before) == 7  # the target itself is opened, not an empty room
    x, y = floor_pixel(page, 1.6, 0.6)
    response = suggest_at(page, x, y)
    added = [o for o in objects(page).values() if o["id"] not in before]
    assert len(added) == 1 and added[0]["category"] == response["suggestions"][0]["category"]
    page.click(".suggestions button.close")
    assert hook(page, "targetObjects()") == 6  # the inset shows the saved target, not the edits
    page.click("#save-button")
    until(page, "window.sceneSuggestTest.saved")
    assert "Saved bedside.json (7 objects)" in page.inner_text("#banner")
    assert hook(page, "targetObjects()") == 7 and page.locator("#target canvas").count() == 1  # the inset shows it
    saved = json.loads((folder / "scenes" / "bedside.json").read_text())
    assert {o["id"] for o in saved["objects"]} == set(before) | {added[0]["id"]}
    assert saved["source"].startswith("authored")  # provenance kept
    page.click("#image-button")
    until(page, "window.sceneSuggestTest.imageSaved", timeout=60)
    image = Image.open(folder / "scenes" / "bedside.png").convert("RGB")
    assert image.size == (1280, 960)
    pixels = np.asarray(image).reshape(-1, 3)
    assert len(np.unique(pixels // 16, axis=0)) > 20  # a rendered scene, not a blank canvas
    screenshot(page, "authoring")
    assert not page.console_problems, page.console_problems


@pytest.fixture(scope="module")
def replication_admin(tmp_path_factory, replication):
    """gunicorn serving the replication with an admin password, for its scene editor (the full condition)."""
    from serverproc import StudyServer
    from werkzeug.security import generate_password_hash

    _require_browser()
    tmp = tmp_path_factory.mktemp("replication-admin")
    make_app(tmp, f"sqlite:///{tmp / 'study.sqlite3'}", studies=[replication])
    server = StudyServer(tmp / "instance", f"sqlite:///{tmp / 'study.sqlite3'}", migrate=False, study=replication)
    server.env["SCENESUGGEST_ADMIN_PASSWORD_HASH"] = generate_password_hash("author-password")
    with server:
        yield server.base


def _facing_error_deg(transform, target_xz) -> float:
    """Angle (degrees) between an object's front and the direction from it to a point, in the floor plane."""
    front = math.atan2(transform[8], transform[10])
    towards = math.atan2(target_xz[0] - transform[12], target_xz[1] - transform[14])
    return abs((math.degrees(front - towards) + 180) % 360 - 180)


def test_oriented_suggestions_face_the_table_and_back_onto_the_wall(page, replication_admin):
    """The replication's dining table and bedroom corner in the scene editor (the full condition): each dining chair
    and the dresser taken away and asked for again with a shift-click where it stood; the suggestion of its category
    comes turned the way the target has it — the chairs facing the table, the dresser's back to the wall."""
    base = replication_admin
    page.goto(f"{base}/admin/login")
    page.fill("input[name=password]", "author-password")
    page.click("button[type=submit]")
    for scene_id, category in (("dining-table", "SideChair"), ("bedroom-corner", "Dresser")):
        page.goto(f"{base}/admin/scenesuggest-2015/author/{scene_id}")
        ready(page)
        table = next((o for o in objects(page).values() if o["category"] == "DiningTable"), None)
        for k, o in enumerate([o for o in objects(page).values() if o["category"] == category]):
            page.evaluate("() => window.sceneSuggestTest.loaded()")
            grab = hook(page, f"grabPixel({o['id']!r})")
            if grab:
                page.mouse.click(*grab)
            else:  # hidden behind the table from this view
                hook(page, f"select({o['id']!r})")
            page.keyboard.press("Delete")
            assert o["id"] not in objects(page)
            x, y = floor_pixel(page, o["contact_point"][0], o["contact_point"][2])
            assert hook(page, f"pickAt({x}, {y}).objectId") == "room"  # the floor where it stood is in view
            before = set(objects(page))
            response = suggest_at(page, x, y)
            assert category in [s["category"] for s in response["suggestions"][:10]]
            page.click(f".suggestions .tile[data-category={category}]")
            until(page, f"window.sceneSuggestTest.objects().some(o => o.category === {category!r} && "
                        f"!{sorted(before)!r}.includes(o.id))")
            [placed] = [p for p in objects(page).values() if p["id"] not in before]
            assert placed["category"] == category
            transform = placed["transform"]
            if table is not None:  # a dining chair faces the table
                assert _facing_error_deg(transform, (table["transform"][12], table["transform"][14])) <= 30
            else:  # the dresser stands with its back to the back wall, facing into the room (+Z)
                assert abs((heading_deg(transform) + 180) % 360 - 180) <= 15
            assert abs(((heading_deg(transform) - heading_deg(o["transform"])) + 180) % 360 - 180) <= 15
            page.click(".suggestions button.close")
            page.evaluate("() => window.sceneSuggestTest.loaded()")
            screenshot(page, f"full-{scene_id}-{category.lower()}-{k}")
    assert not page.console_problems, page.console_problems
